// CloudScales: the lengths that describe how a cloud is sampled, measured once from the data.
// One mean spacing does not describe a LiDAR scan: its rings are 2-3 cm apart next to the sensor
// and decimetres apart 30 m away. The scales below hold for a 5 cm statue and a 50 m street
// alike, and the registration derives every length it uses from them (registration/scales.h).
#pragma once

#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/sensor_view.h"

namespace mlsreg {

// The working voxel is this fraction of the cloud's robust extent: about 3 d on a turntable scan
// (the bunny: 3.2 d), 0.75 m on a KITTI Velodyne scan (KISS-ICP takes 1 % of the sensor's range).
inline constexpr double kWorkingVoxelPerExtent = 0.01;
// ...and at least this many median spacings, so that a voxel holds several samples.
inline constexpr double kMinWorkingVoxelPerSpacing = 2.0;

struct CloudScales {
  double mean_spacing = 0.0;    // d: mean nearest-neighbour distance (paper Eq. 11), sampled
  double median_spacing = 0.0;  // of the nearest-neighbour distances
  double spacing_p90 = 0.0;     // 90th percentile: the sparse regions
  // Twice the 95th percentile of the distances from the component-wise median point: the size of
  // the scene, robust to a few far outliers.
  double extent = 0.0;
  double working_voxel = 0.0;  // the coarse resolution: max(1 % extent, 2 median spacings)
  // The scan's sensor, when its sampling shows one (FindSensor, at the viewpoint or the origin).
  std::optional<SensorFinding> sensor;
};

// Measures the scales of `points` (indexed by `tree`) from the nearest distinct neighbours of a
// seeded sample of at most 20,000 of them (every point of a smaller cloud; the same for any
// `threads`): their mean the mean spacing (SamplingDistance's value up to the sampling: exactly
// it up to 20,000 points), their percentiles, and the sensor, looked for at `viewpoint` (the
// origin when none is known). A cloud with no two distinct points has mean spacing 0.
CloudScales MeasureScales(const std::vector<Vec3>& points, const KdTree& tree,
                          const std::optional<Vec3>& viewpoint = std::nullopt, int threads = 1);

// The sensor of a scan alone, found as MeasureScales finds it but from a seeded sample of at most
// 5,000 points (their nearest distinct neighbours only): for a source, whose other scales the
// registration does not need.
std::optional<SensorFinding> FindScanSensor(const std::vector<Vec3>& points, const KdTree& tree,
                                            const std::optional<Vec3>& viewpoint = std::nullopt,
                                            int threads = 1);

}  // namespace mlsreg
