// Target: a validated target cloud with everything registrations reuse, built once.
#pragma once

#include <memory>

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/cloud_scales.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/mls_patches.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/geometry/surface_analysis.h"
#include "mlsreg/geometry/voxel_cloud.h"

namespace mlsreg {

struct TargetOptions {
  // Radius of the Wendland-weighted PCA giving per-point normals and surface variation (used by
  // closest-point correspondences and their filters), in units of the sampling distance d.
  double analysis_radius_d = 5.0;
  // Minimum number of points accepted.
  std::size_t min_points = 10;
  // Threads of the build's per-point analysis (the target is the same for any count).
  int threads = 1;
  // Build the MLS patches (geometry/mls_patches.h) at the automatic radius of the target's
  // noise (geometry/mls_radius.h), so MLS correspondences against it cost about what closest
  // points do.
  bool build_mls_patches = true;
  // Build the FPFH features of global registration (geometry/feature_cloud.h) at the scale
  // chosen from d, so that registrations from an unknown start reuse them.
  bool build_global_features = true;
};

// Cloud + kd-tree + sampling distance + per-point surface properties. Immutable once built and
// safe to share between concurrent registrations (all queries are const).
class Target {
 public:
  // CANCELLED when `should_stop` (asked every few hundred points) says stop.
  static absl::StatusOr<std::shared_ptr<const Target>> Build(PointCloud cloud,
                                                             const TargetOptions& options = {},
                                                             const StopCheck& should_stop = {});

  // This target with its points moved (same count and order; ST-SICP's smoothed copy): index,
  // d, normals and depth grid are rebuilt, the surface variation is kept from this target.
  // Smoothing flattens surface variation, so rebuilt values would set the curvature filter
  // against every noisy source.
  absl::StatusOr<std::shared_ptr<const Target>> WithMovedPoints(std::vector<Vec3> points) const;

  const PointCloud& cloud() const { return cloud_; }
  const std::vector<Vec3>& points() const { return cloud_.points; }
  const KdTree& tree() const { return *tree_; }
  const SurfaceProperties& surface() const { return surface_; }
  // The organised grid when the cloud carries pinhole intrinsics, else null.
  const DepthGrid* grid() const { return grid_ ? &*grid_ : nullptr; }
  // Mean nearest-neighbour distance d (paper Eq. 11).
  double sampling_distance() const { return sampling_distance_; }
  // How the cloud is sampled: spacing percentiles, extent, the working voxel.
  const CloudScales& scales() const { return scales_; }
  // The cloud at its working voxel (scales().working_voxel), with normals and an index.
  const VoxelCloud& voxel_cloud() const { return voxel_cloud_; }
  const TargetOptions& options() const { return options_; }
  double build_seconds() const { return build_seconds_; }
  // The noise of the cloud, estimated once at build time (EstimateNoise).
  const NoiseEstimate& noise() const { return noise_; }
  // The MLS surface as patches at the automatic radius of noise() (null when not built).
  const MlsPatches* mls_patches() const { return mls_patches_ ? &*mls_patches_ : nullptr; }
  // The features of global registration (null when not built).
  const FeatureCloud* features() const { return features_ ? &*features_ : nullptr; }
  // Heap bytes held (points, normals, properties, index, MLS patches, features).
  std::size_t MemoryBytes() const;
  // A lower bound of MemoryBytes() for a cloud of this shape, known before any build: points,
  // normals if any, the per-point normal, curvature and validity the build adds, and the depth
  // grid of an organised scan (the kd-tree comes on top).
  static std::uint64_t EstimateBytes(std::uint64_t point_count, bool has_normals,
                                     const std::optional<PinholeIntrinsics>& intrinsics);

 private:
  Target() = default;
  static absl::StatusOr<std::shared_ptr<Target>> BuildMutable(PointCloud cloud,
                                                              const TargetOptions& options,
                                                              const StopCheck& should_stop);
  PointCloud cloud_;
  std::unique_ptr<KdTree> tree_;
  SurfaceProperties surface_;
  std::optional<DepthGrid> grid_;
  double sampling_distance_ = 0.0;
  CloudScales scales_;
  VoxelCloud voxel_cloud_;
  TargetOptions options_;
  double build_seconds_ = 0.0;
  NoiseEstimate noise_;
  std::optional<MlsPatches> mls_patches_;
  std::optional<FeatureCloud> features_;
};

}  // namespace mlsreg
