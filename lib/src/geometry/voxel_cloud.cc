#include "mlsreg/geometry/voxel_cloud.h"

#include <algorithm>

#include "absl/container/flat_hash_map.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/geometry/weighted_covariance.h"
#include "voxel_key.h"

namespace mlsreg {

std::size_t VoxelCloud::MemoryBytes() const {
  return points.capacity() * sizeof(Vec3) + normals.capacity() * sizeof(Vec3) + valid.capacity() +
         planarity.capacity() * sizeof(float) + spread.capacity() * sizeof(float) +
         counts.capacity() * sizeof(std::uint32_t) + (tree ? tree->MemoryBytes() : 0);
}

namespace {

// The samples of each occupied voxel: their count, mean and second moment about the first one.
struct VoxelMoments {
  std::vector<Vec3> centroids;
  std::vector<Eigen::Matrix3d> scatter;  // sum of (p - first)(p - first)^T
  std::vector<Vec3> first;
  std::vector<std::uint32_t> counts;
};

VoxelMoments Accumulate(const std::vector<Vec3>& points, double voxel, bool with_scatter) {
  absl::flat_hash_map<internal::VoxelKey, std::uint32_t, internal::VoxelKeyHash> slot;
  slot.reserve(points.size() / 4 + 1);
  VoxelMoments m;
  std::vector<Vec3> sums;
  const double inv_voxel = 1.0 / voxel;
  for (const Vec3& p : points) {
    const auto [it, inserted] =
        slot.try_emplace(internal::KeyOf(p, inv_voxel), static_cast<std::uint32_t>(sums.size()));
    if (inserted) {
      sums.push_back(Vec3::Zero());
      m.counts.push_back(0);
      m.first.push_back(p);
      if (with_scatter) m.scatter.push_back(Eigen::Matrix3d::Zero());
    }
    const std::uint32_t k = it->second;
    const Vec3 offset = p - m.first[k];
    sums[k] += offset;
    ++m.counts[k];
    if (with_scatter) m.scatter[k].noalias() += offset * offset.transpose();
  }
  m.centroids.resize(sums.size());
  for (std::size_t k = 0; k < sums.size(); ++k) {
    m.centroids[k] = m.first[k] + sums[k] / m.counts[k];
  }
  return m;
}

}  // namespace

std::vector<Vec3> VoxelCentroids(const std::vector<Vec3>& points, double voxel) {
  return Accumulate(points, voxel, false).centroids;
}

VoxelCloud BuildVoxelCloud(const std::vector<Vec3>& points, double voxel,
                           const std::optional<Vec3>& viewpoint, int threads) {
  VoxelCloud cloud;
  cloud.voxel = voxel;
  VoxelMoments moments = Accumulate(points, voxel, true);
  cloud.points = std::move(moments.centroids);
  const std::size_t n = cloud.points.size();
  cloud.spread.assign(n, -1.0f);
  cloud.normals.assign(n, Vec3::Zero());
  cloud.valid.assign(n, 0);
  cloud.planarity.assign(n, 0.0f);
  cloud.oriented = viewpoint.has_value();
  cloud.tree = std::make_unique<KdTree>(cloud.points, threads);
  ParallelFor(
      n, threads,
      [&](std::size_t begin, std::size_t end, int) {
        std::uint32_t index[kVoxelNormalNeighbors];
        double d2[kVoxelNormalNeighbors];
        for (std::size_t i = begin; i < end; ++i) {
          const std::size_t found =
              cloud.tree->Knn(cloud.points[i], kVoxelNormalNeighbors, index, d2);
          if (found < 5) continue;
          WeightedCovariance covariance(cloud.points[i]);
          for (std::size_t j = 0; j < found; ++j) covariance.Add(cloud.points[index[j]], 1.0);
          LocalFrame frame;
          if (!covariance.Finalize(frame)) continue;
          Vec3 normal = frame.normal;
          if (viewpoint && normal.dot(*viewpoint - cloud.points[i]) < 0.0) normal = -normal;
          cloud.normals[i] = normal;
          cloud.valid[i] = 1;
          cloud.planarity[i] = static_cast<float>(1.0 - 3.0 * frame.surface_variation);
          const std::uint32_t c = moments.counts[i];
          if (c >= 3) {
            const Vec3 mean = (cloud.points[i] - moments.first[i]);
            const double along =
                normal.dot(moments.scatter[i] * normal) / c - Eigen::numext::abs2(normal.dot(mean));
            cloud.spread[i] = static_cast<float>(std::sqrt(std::max(0.0, along)));
          }
        }
      },
      256);
  // Voxels of too few samples (or no normal): the median of their neighbours' spreads.
  std::vector<float> borrowed(n, 0.0f);
  ParallelFor(
      n, threads,
      [&](std::size_t begin, std::size_t end, int) {
        std::uint32_t index[kVoxelNormalNeighbors];
        double d2[kVoxelNormalNeighbors];
        float known[kVoxelNormalNeighbors];
        for (std::size_t i = begin; i < end; ++i) {
          if (cloud.spread[i] >= 0.0f) continue;
          const std::size_t found =
              cloud.tree->Knn(cloud.points[i], kVoxelNormalNeighbors, index, d2);
          std::size_t count = 0;
          for (std::size_t j = 0; j < found; ++j) {
            if (moments.counts[index[j]] >= 3 && cloud.valid[index[j]]) {
              known[count++] = cloud.spread[index[j]];
            }
          }
          if (count == 0) continue;
          std::nth_element(known, known + count / 2, known + count);
          borrowed[i] = known[count / 2];
        }
      },
      256);
  for (std::size_t i = 0; i < n; ++i) {
    if (cloud.spread[i] < 0.0f) cloud.spread[i] = borrowed[i];
  }
  cloud.counts = std::move(moments.counts);
  return cloud;
}

}  // namespace mlsreg
