#include "mlsreg/geometry/feature_cloud.h"

#include <cmath>

#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/voxel_cloud.h"

namespace mlsreg {
namespace {

constexpr int kMaxScaleRounds = 4;
constexpr std::uint64_t kSubsetSeed = 0x5eed;

}  // namespace

std::size_t FeatureCloud::MemoryBytes() const {
  return points.capacity() * sizeof(Vec3) + normals.capacity() * sizeof(Vec3) +
         features.capacity() * sizeof(FpfhFeature);
}

FeatureScale ChooseFeatureScale(const std::vector<Vec3>& points, double d) {
  double voxel = kFeatureVoxelD * d;
  for (int round = 0; round < kMaxScaleRounds; ++round) {
    const std::size_t count = VoxelRepresentatives(points, voxel).size();
    if (count <= kMaxFeatureSamples) break;
    // A surface's voxel count falls with the square of the voxel edge.
    voxel *= 1.05 * std::sqrt(static_cast<double>(count) / kMaxFeatureSamples);
  }
  return {voxel, kFeatureRadiusPerVoxel * voxel, 2 * kMaxFeatureSamples};
}

FeatureScale FeatureScaleFor(const std::vector<Vec3>& points, const CloudScales& scales) {
  double voxel = std::max(scales.working_voxel, kFeatureVoxelSpacings * scales.median_spacing);
  for (int round = 0; round < kMaxScaleRounds; ++round) {
    const std::size_t count = VoxelRepresentatives(points, voxel).size();
    if (count <= kMaxVoxelFeatureSamples) break;
    voxel *= 1.05 * std::sqrt(static_cast<double>(count) / kMaxVoxelFeatureSamples);
  }
  return {voxel, kFeatureRadiusPerVoxel * voxel, kMaxVoxelFeatureSamples};
}

std::optional<FeatureCloud> BuildVoxelFeatureCloud(const std::vector<Vec3>& points,
                                                   const FeatureScale& scale,
                                                   const std::optional<Vec3>& viewpoint,
                                                   const StopCheck& should_stop, int threads) {
  VoxelCloud voxels = BuildVoxelCloud(points, scale.voxel, viewpoint, threads);
  std::vector<std::uint32_t> kept;
  for (std::uint32_t i = 0; i < voxels.size(); ++i) {
    if (voxels.valid[i]) kept.push_back(i);
  }
  if (kept.size() > scale.max_samples) {
    const std::vector<std::uint32_t> subset =
        RandomSubsample(kept.size(), scale.max_samples, kSubsetSeed);
    for (std::size_t k = 0; k < subset.size(); ++k) kept[k] = kept[subset[k]];
    kept.resize(subset.size());
  }
  FeatureCloud out;
  out.scale = scale;
  out.oriented = voxels.oriented;
  out.points.reserve(kept.size());
  out.normals.reserve(kept.size());
  for (std::uint32_t i : kept) {
    out.points.push_back(voxels.points[i]);
    out.normals.push_back(voxels.normals[i]);
  }
  if (!ComputeFeatures(out, should_stop, threads)) return std::nullopt;
  return out;
}

std::optional<FeatureCloud> SampleOrientedPoints(
    const std::vector<Vec3>& points, const KdTree& tree, const SurfaceProperties* surface,
    double normal_radius, const std::optional<Vec3>& viewpoint, const FeatureScale& scale,
    const StopCheck& should_stop) {
  std::vector<std::uint32_t> samples = VoxelRepresentatives(points, scale.voxel);
  if (samples.size() > scale.max_samples) {
    const std::vector<std::uint32_t> keep =
        RandomSubsample(samples.size(), scale.max_samples, kSubsetSeed);
    for (std::size_t k = 0; k < keep.size(); ++k) samples[k] = samples[keep[k]];
    samples.resize(keep.size());
  }
  FeatureCloud out;
  out.scale = scale;
  SurfaceProperties analysed;
  if (!surface) {
    analysed = AnalyzeSurface(points, tree, normal_radius, viewpoint, samples, should_stop);
    if (analysed.stopped) return std::nullopt;
  }
  out.oriented = surface ? surface->oriented : analysed.oriented;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const std::uint32_t i = samples[k];
    const bool valid = surface ? surface->valid[i] != 0 : analysed.valid[k] != 0;
    if (!valid) continue;
    out.points.push_back(points[i]);
    out.normals.push_back(surface ? surface->normals[i] : analysed.normals[k]);
  }
  return out;
}

bool ComputeFeatures(FeatureCloud& cloud, const StopCheck& should_stop, int threads) {
  cloud.features.clear();
  if (cloud.points.empty()) return !(should_stop && should_stop());
  const KdTree sample_tree(cloud.points, threads);
  cloud.features = ComputeFpfh(cloud.points, cloud.normals, sample_tree, cloud.scale.feature_radius,
                               should_stop, threads);
  return cloud.features.size() == cloud.points.size();
}

std::optional<FeatureCloud> BuildFeatureCloud(const std::vector<Vec3>& points, const KdTree& tree,
                                              const SurfaceProperties* surface,
                                              double normal_radius,
                                              const std::optional<Vec3>& viewpoint,
                                              const FeatureScale& scale,
                                              const StopCheck& should_stop) {
  std::optional<FeatureCloud> out =
      SampleOrientedPoints(points, tree, surface, normal_radius, viewpoint, scale, should_stop);
  if (!out || !ComputeFeatures(*out, should_stop)) return std::nullopt;
  return out;
}

}  // namespace mlsreg
