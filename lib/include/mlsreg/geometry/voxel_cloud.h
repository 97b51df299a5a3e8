// VoxelCloud: a cloud at a coarser working resolution, one point per occupied voxel (the centroid
// of the samples in it), each with a normal from its nearest voxel neighbours, and an index.
// What coarse alignment matches against, and what verification and global registration sample:
// a voxel cloud follows the surface, where the raw samples of a spinning LiDAR follow the
// sensor's rings (dense near it, decimetres apart far away).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

// Normals come from the plane of this many nearest voxel points: a count, not a radius, so the
// support follows the density of the cloud wherever it is sampled.
inline constexpr int kVoxelNormalNeighbors = 12;

struct VoxelCloud {
  double voxel = 0.0;               // edge length (absolute units)
  std::vector<Vec3> points;         // centroids, in the order of their first sample in the cloud
  std::vector<Vec3> normals;        // unit; oriented toward the viewpoint when `oriented`
  std::vector<std::uint8_t> valid;  // 0 where the neighbourhood is degenerate (normal unusable)
  std::vector<float> planarity;     // 1 - surface variation * 3, in [0, 1]
  // The RMS distance of the voxel's samples from the plane through their centroid with the
  // voxel's normal: the local noise where the surface is flat at the voxel's scale (it grows
  // with range on a LiDAR scan), noise plus shape elsewhere. Voxels of fewer than 3 samples take
  // the median of their neighbours'.
  std::vector<float> spread;
  std::vector<std::uint32_t> counts;  // samples in each voxel
  bool oriented = false;
  std::unique_ptr<KdTree> tree;  // over `points`
  // The sensor of the scan the voxels come from, when its sampling shows one (FindScanSensor;
  // not set by BuildVoxelCloud): the verification asks from which side it saw each surface.
  std::optional<Vec3> sensor;

  std::size_t size() const { return points.size(); }
  std::size_t MemoryBytes() const;
};

// The voxel cloud of `points` at edge `voxel` (> 0). Normals are oriented toward `viewpoint` when
// given. `threads` split the normal estimation; the result is the same for any count.
VoxelCloud BuildVoxelCloud(const std::vector<Vec3>& points, double voxel,
                           const std::optional<Vec3>& viewpoint, int threads = 1);

// The centroid of the samples in each occupied voxel of edge `voxel`, in the order of each
// voxel's first sample.
std::vector<Vec3> VoxelCentroids(const std::vector<Vec3>& points, double voxel);

}  // namespace mlsreg
