// Target: a validated target cloud with everything registrations reuse, built once.
#pragma once

#include <cstdint>
#include <memory>

#include "absl/status/statusor.h"
#include "mlsreg/core/on_demand.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/cloud_scales.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/mls_patches.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/geometry/sensor_view.h"
#include "mlsreg/geometry/surface_analysis.h"
#include "mlsreg/geometry/voxel_cloud.h"

namespace mlsreg {

// When a derived part of a target is made: by Target::Build, so that the first registration pays
// nothing for it, or by the first registration that needs it (thread-safe; a part no method asks
// for is never made). Registrations give the same results either way.
enum class PartBuild : std::uint8_t { kWithTarget, kOnFirstUse };

struct TargetOptions {
  // Radius of the Wendland-weighted PCA giving per-point normals and surface variation (used by
  // closest-point correspondences and their filters), in units of the sampling distance d.
  double analysis_radius_d = 5.0;
  // Minimum number of points accepted.
  std::size_t min_points = 10;
  // Threads of the build's per-point analysis (the target is the same for any count).
  int threads = 1;
  // Per-point normals and surface variation (surface()): closest-point matching and its filters,
  // G-ICP, FGR, multi-view. MLS matching and `auto` do not need them.
  PartBuild surface = PartBuild::kOnFirstUse;
  // The fits of the MLS patches (geometry/mls_patches.h) at the automatic radius of the target's
  // noise (geometry/mls_radius.h); their anchors and storage are made by Build either way, so
  // the target's memory does not grow. On first use, only the patches near a source are fitted.
  PartBuild mls_patch_fits = PartBuild::kOnFirstUse;
  // The FPFH features of global registration (geometry/feature_cloud.h) at the scale chosen from
  // the cloud's scales: `auto` needs them only when its start does not verify.
  PartBuild global_features = PartBuild::kOnFirstUse;

  // Every part made by Build.
  static TargetOptions AllWithTarget() {
    TargetOptions options;
    options.surface = options.mls_patch_fits = options.global_features = PartBuild::kWithTarget;
    return options;
  }
  // A served target: its bytes are all there at upload (the cache counts them once), so the
  // surface and features are made with it; the patches' storage too, fitted where
  // registrations query them.
  static TargetOptions ForServing() {
    TargetOptions options = AllWithTarget();
    options.mls_patch_fits = PartBuild::kOnFirstUse;
    return options;
  }
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
  // d, normals and depth grid are rebuilt (no MLS patches or features), the surface variation is
  // kept from this target.
  // Smoothing flattens surface variation, so rebuilt values would set the curvature filter
  // against every noisy source.
  absl::StatusOr<std::shared_ptr<const Target>> WithMovedPoints(std::vector<Vec3> points) const;

  const PointCloud& cloud() const { return cloud_; }
  const std::vector<Vec3>& points() const { return cloud_.points; }
  const KdTree& tree() const { return *tree_; }
  // Made on first call unless built with the target (TargetOptions::surface); not cancellable.
  const SurfaceProperties& surface() const;
  // Whether normals (the surface's, the MLS projections') point toward a known viewpoint.
  bool oriented() const { return cloud_.viewpoint.has_value(); }
  // The organised grid when the cloud carries pinhole intrinsics, else null.
  const DepthGrid* grid() const { return grid_ ? &*grid_ : nullptr; }
  // Mean nearest-neighbour distance d (paper Eq. 11).
  double sampling_distance() const { return sampling_distance_; }
  // How the cloud is sampled: spacing percentiles, extent, the working voxel.
  const CloudScales& scales() const { return scales_; }
  // The scan's sensor when its sampling shows one (scales().sensor): its MLS patches' supports
  // grow across the scan lines, and say when they hold one line (MlsPatches).
  const std::optional<SensorFinding>& scan_sensor() const { return scales_.sensor; }
  // The cloud at its working voxel (scales().working_voxel), with normals and an index.
  const VoxelCloud& voxel_cloud() const { return voxel_cloud_; }
  // What the scan's sensor saw, when the sampling shows a sensor (scales().sensor), else null.
  const SensorView* sensor_view() const { return sensor_view_ ? &*sensor_view_ : nullptr; }
  const TargetOptions& options() const { return options_; }
  double build_seconds() const { return build_seconds_; }
  // The noise of the cloud, estimated once at build time (EstimateNoise).
  const NoiseEstimate& noise() const { return noise_; }
  // The MLS surface as patches at the automatic radius of noise() (null when not built: the
  // Algorithm 1 projection then runs exactly).
  const MlsPatches* mls_patches() const { return mls_patches_ ? &*mls_patches_ : nullptr; }
  // The features of global registration, made on first call unless built with the target; null
  // when `should_stop` said stop while they were being made.
  const FeatureCloud* features(const StopCheck& should_stop = {}) const;
  // Heap bytes held now (points, normals, properties, index, MLS patches, features).
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
                                                              const StopCheck& should_stop,
                                                              bool with_patches);
  SurfaceProperties AnalyzeOwnSurface(const StopCheck& should_stop) const;
  std::optional<FeatureCloud> BuildFeatures(const StopCheck& should_stop) const;
  PointCloud cloud_;
  std::unique_ptr<KdTree> tree_;
  OnDemand<SurfaceProperties> surface_;
  std::optional<DepthGrid> grid_;
  double sampling_distance_ = 0.0;
  CloudScales scales_;
  VoxelCloud voxel_cloud_;
  std::optional<SensorView> sensor_view_;
  TargetOptions options_;
  double build_seconds_ = 0.0;
  NoiseEstimate noise_;
  std::optional<MlsPatches> mls_patches_;
  OnDemand<FeatureCloud> features_;
};

}  // namespace mlsreg
