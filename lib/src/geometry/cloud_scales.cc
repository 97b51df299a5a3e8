#include "mlsreg/geometry/cloud_scales.h"

#include <algorithm>
#include <cmath>

#include "mlsreg/core/quantile.h"
#include "mlsreg/geometry/sampling.h"

namespace mlsreg {
namespace {

constexpr std::size_t kSpacingSamples = 20'000;
constexpr std::uint64_t kSpacingSeed = 0x5ca1e;
// FindScanSensor's sample: enough for the slope of log spacing over log range (FindSensor).
constexpr std::size_t kSensorSamples = 5'000;

}  // namespace

CloudScales MeasureScales(const std::vector<Vec3>& points, const KdTree& tree,
                          const std::optional<Vec3>& viewpoint, int threads) {
  CloudScales scales;
  if (points.empty()) return scales;
  // One seeded sample gives every spacing: on 120k-point LiDAR scans its mean differs from that
  // of every point by 0.04 % (KITTI 00 frame 0) to 0.11 % (a tuning street), and its searches
  // take a sixth of the time.
  const std::vector<std::uint32_t> sample =
      RandomSubsample(points.size(), kSpacingSamples, kSpacingSeed);
  const std::vector<double> sampled = NearestDistinctDistances(points, tree, sample, threads);
  const double d = MeanFoundDistance(sampled);
  scales.mean_spacing = d;
  scales.sensor = FindSensor(points, sample, sampled, viewpoint.value_or(Vec3::Zero()));
  std::vector<double> spacing;
  spacing.reserve(sample.size());
  for (const double s : sampled) {
    if (s >= 0.0) spacing.push_back(s);
  }
  scales.median_spacing = QuantileInPlace(spacing, 0.5);
  scales.spacing_p90 = QuantileInPlace(spacing, 0.9);

  std::vector<double> coordinate(sample.size());
  Vec3 median;
  for (int axis = 0; axis < 3; ++axis) {
    for (std::size_t k = 0; k < sample.size(); ++k) coordinate[k] = points[sample[k]][axis];
    median[axis] = QuantileInPlace(coordinate, 0.5);
  }
  std::vector<double> radius(sample.size());
  for (std::size_t k = 0; k < sample.size(); ++k) radius[k] = (points[sample[k]] - median).norm();
  scales.extent = 2.0 * QuantileInPlace(radius, 0.95);
  scales.working_voxel = std::max(kWorkingVoxelPerExtent * scales.extent,
                                  kMinWorkingVoxelPerSpacing * scales.median_spacing);
  if (!(scales.working_voxel > 0.0)) scales.working_voxel = d;
  return scales;
}

std::optional<SensorFinding> FindScanSensor(const std::vector<Vec3>& points, const KdTree& tree,
                                            const std::optional<Vec3>& viewpoint, int threads) {
  if (points.empty()) return std::nullopt;
  const std::vector<std::uint32_t> sample =
      RandomSubsample(points.size(), kSensorSamples, kSpacingSeed);
  const std::vector<double> sampled = NearestDistinctDistances(points, tree, sample, threads);
  return FindSensor(points, sample, sampled, viewpoint.value_or(Vec3::Zero()));
}

}  // namespace mlsreg
