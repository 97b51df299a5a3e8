// FeatureCloud: a voxel subsample of a cloud with a normal and an FPFH feature per sample, what
// global registration matches. The scale comes from the target's sampling distance d: voxels of
// kFeatureVoxelD * d (grown when the cloud would give more than kMaxFeatureSamples samples),
// features over 5 voxels (Open3D's and FGR's voxel : feature ratio).
#pragma once

#include <optional>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/cloud_scales.h"
#include "mlsreg/geometry/fpfh.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/surface_analysis.h"

namespace mlsreg {

inline constexpr double kFeatureVoxelD = 3.0;
inline constexpr double kFeatureRadiusPerVoxel = 5.0;
// Feature matching is quadratic in the samples: larger clouds get larger voxels.
inline constexpr std::size_t kMaxFeatureSamples = 2500;

// The scale and size of a feature cloud.
struct FeatureScale {
  double voxel = 0.0;           // absolute units
  double feature_radius = 0.0;  // absolute units
  // A seeded random subset of the voxel samples is kept beyond this many.
  std::size_t max_samples = 2 * kMaxFeatureSamples;
};

struct FeatureCloud {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;  // unit; oriented toward the viewpoint when `oriented`
  std::vector<FpfhFeature> features;
  FeatureScale scale;
  bool oriented = false;

  std::size_t size() const { return points.size(); }
  std::size_t MemoryBytes() const;
};

// The scale for a cloud of `points` with sampling distance `d`: kFeatureVoxelD * d, grown until
// the voxel subsample has at most kMaxFeatureSamples samples.
FeatureScale ChooseFeatureScale(const std::vector<Vec3>& points, double d);

// The voxel representatives of `points` at `scale` with their normals, without features: the
// first half of BuildFeatureCloud, what verification needs. Same arguments.
std::optional<FeatureCloud> SampleOrientedPoints(
    const std::vector<Vec3>& points, const KdTree& tree, const SurfaceProperties* surface,
    double normal_radius, const std::optional<Vec3>& viewpoint, const FeatureScale& scale,
    const StopCheck& should_stop = {});
// The second half: the FPFH features of `cloud`'s samples at its scale, on `threads`. False when
// stopped.
bool ComputeFeatures(FeatureCloud& cloud, const StopCheck& should_stop = {}, int threads = 1);

// The features at `scale` of the voxel representatives of `points` (`tree` indexes them). Normals
// come from `surface` (a per-point analysis of all of `points`) when given, else from an analysis
// at `normal_radius` of the representatives alone, oriented toward `viewpoint` when given. A
// cloud larger than the target may give more than kMaxFeatureSamples samples; a seeded random
// subset of them (scale.max_samples) is kept. Samples without a valid normal are dropped. nullopt
// when `should_stop` said stop.
// The scale of global registration for a target sampled as `scales` says: voxels of its working
// voxel, at least kFeatureVoxelSpacings median spacings (features need several samples per
// voxel), grown until the target gives at most kMaxVoxelFeatureSamples of them; features over
// kFeatureRadiusPerVoxel voxels. A KITTI scan gets 0.75-1 m voxels, an object scan about 3 d.
inline constexpr double kFeatureVoxelSpacings = 3.0;
inline constexpr std::size_t kMaxVoxelFeatureSamples = 3000;
FeatureScale FeatureScaleFor(const std::vector<Vec3>& points, const CloudScales& scales);

// The features of `points` at `scale` on their voxel cloud (voxel centroids, normals from their
// nearest voxel neighbours, oriented toward `viewpoint` when given), a seeded random subset of
// scale.max_samples when there are more. nullopt when `should_stop` said stop.
std::optional<FeatureCloud> BuildVoxelFeatureCloud(const std::vector<Vec3>& points,
                                                   const FeatureScale& scale,
                                                   const std::optional<Vec3>& viewpoint,
                                                   const StopCheck& should_stop = {},
                                                   int threads = 1);

std::optional<FeatureCloud> BuildFeatureCloud(const std::vector<Vec3>& points, const KdTree& tree,
                                              const SurfaceProperties* surface,
                                              double normal_radius,
                                              const std::optional<Vec3>& viewpoint,
                                              const FeatureScale& scale,
                                              const StopCheck& should_stop = {});

}  // namespace mlsreg
