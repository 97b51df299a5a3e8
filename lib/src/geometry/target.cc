#include "mlsreg/geometry/target.h"

#include <chrono>

#include "absl/strings/str_cat.h"
#include "mlsreg/geometry/mls_radius.h"
#include "mlsreg/geometry/sampling.h"

namespace mlsreg {

absl::StatusOr<std::shared_ptr<const Target>> Target::Build(PointCloud cloud,
                                                            const TargetOptions& options,
                                                            const StopCheck& should_stop) {
  absl::StatusOr<std::shared_ptr<Target>> target =
      BuildMutable(std::move(cloud), options, should_stop, /*with_patches=*/true);
  if (!target.ok()) return target.status();
  return std::shared_ptr<const Target>(*std::move(target));
}

absl::StatusOr<std::shared_ptr<const Target>> Target::WithMovedPoints(
    std::vector<Vec3> points) const {
  if (points.size() != cloud_.points.size()) {
    return absl::InvalidArgumentError("WithMovedPoints: the point count must not change");
  }
  PointCloud moved = cloud_;
  moved.points = std::move(points);
  moved.normals.clear();
  TargetOptions options = options_;
  options.surface = PartBuild::kWithTarget;  // its curvature is replaced below
  options.global_features = PartBuild::kOnFirstUse;
  absl::StatusOr<std::shared_ptr<Target>> target =
      BuildMutable(std::move(moved), options, {}, /*with_patches=*/false);
  if (!target.ok()) return target.status();
  SurfaceProperties surface = (*target)->surface();
  surface.curvature = this->surface().curvature;
  (*target)->surface_.Set(std::move(surface));  // not shared yet
  return std::shared_ptr<const Target>(*std::move(target));
}

absl::StatusOr<std::shared_ptr<Target>> Target::BuildMutable(PointCloud cloud,
                                                             const TargetOptions& options,
                                                             const StopCheck& should_stop,
                                                             bool with_patches) {
  if (absl::Status s = ValidatePointCloud(cloud, options.min_points); !s.ok()) return s;
  if (absl::Status s = CheckCoordinateRange(cloud); !s.ok()) return s;
  if (cloud.intrinsics) {  // before anything is allocated for it
    if (absl::Status s = ValidateIntrinsicsFor(*cloud.intrinsics, cloud.size(), "intrinsics");
        !s.ok()) {
      return s;
    }
  }
  auto cancelled = [] { return absl::CancelledError("target build cancelled"); };
  if (!(options.analysis_radius_d > 0.0)) {
    return absl::InvalidArgumentError("analysis_radius_d must be positive");
  }
  const auto start = std::chrono::steady_clock::now();
  std::shared_ptr<Target> target(new Target());
  target->cloud_ = std::move(cloud);
  target->cloud_.colors = {};  // never used by registration: not held
  target->options_ = options;
  target->tree_ = std::make_unique<KdTree>(target->cloud_.points, options.threads);
  if (should_stop && should_stop()) return cancelled();
  // One nearest-neighbour pass gives d (the mean spacing) and the spacing percentiles.
  target->scales_ = MeasureScales(target->cloud_.points, *target->tree_, target->cloud_.viewpoint,
                                  options.threads);
  target->sampling_distance_ = target->scales_.mean_spacing;
  if (!(target->sampling_distance_ > 0.0)) {
    return absl::InvalidArgumentError("target has no two distinct points (sampling distance 0)");
  }
  target->voxel_cloud_ = BuildVoxelCloud(target->cloud_.points, target->scales_.working_voxel,
                                         target->cloud_.viewpoint, options.threads);
  if (target->scales_.sensor) {
    target->sensor_view_ = SensorView::Build(target->cloud_.points, *target->scales_.sensor);
  }
  if (should_stop && should_stop()) return cancelled();
  if (options.surface == PartBuild::kWithTarget) {
    SurfaceProperties surface = target->AnalyzeOwnSurface(should_stop);
    if (surface.stopped) return cancelled();
    target->surface_.Set(std::move(surface));
  }
  target->noise_ = EstimateNoise(target->cloud_.points, *target->tree_, target->sampling_distance_,
                                 {}, {}, should_stop, options.threads);
  if (target->noise_.stopped) return cancelled();
  if (with_patches) {
    MlsOptions mls;
    mls.radius = AutoMlsRadiusD(target->noise_.sigma_d) * target->sampling_distance_;
    const PatchFitting fitting = options.mls_patch_fits == PartBuild::kWithTarget
                                     ? PatchFitting::kAll
                                     : PatchFitting::kOnFirstUse;
    absl::StatusOr<MlsPatches> patches =
        MlsPatches::Build(target->cloud_.points, *target->tree_, mls, target->cloud_.viewpoint,
                          fitting, options.threads, should_stop, target->scan_sensor());
    if (absl::IsCancelled(patches.status())) return cancelled();
    // A cloud no patch fits (no 3 samples within r anywhere) is still a target: MLS matching
    // against it then runs the exact Algorithm 1, which reports the same shortage per query.
    if (patches.ok()) target->mls_patches_ = *std::move(patches);
  }
  if (options.global_features == PartBuild::kWithTarget) {
    std::optional<FeatureCloud> features = target->BuildFeatures(should_stop);
    if (!features) return cancelled();
    target->features_.Set(*std::move(features));
  }
  if (target->cloud_.intrinsics) {
    auto grid = DepthGrid::Build(target->cloud_.points, *target->cloud_.intrinsics);
    if (!grid.ok()) return grid.status();
    target->grid_ = *std::move(grid);
  }
  target->build_seconds_ =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return target;
}

SurfaceProperties Target::AnalyzeOwnSurface(const StopCheck& should_stop) const {
  return AnalyzeSurface(cloud_.points, *tree_, options_.analysis_radius_d * sampling_distance_,
                        cloud_.viewpoint, {}, should_stop, options_.threads);
}

std::optional<FeatureCloud> Target::BuildFeatures(const StopCheck& should_stop) const {
  return BuildVoxelFeatureCloud(cloud_.points, FeatureScaleFor(cloud_.points, scales_),
                                cloud_.viewpoint, should_stop, options_.threads);
}

const SurfaceProperties& Target::surface() const {
  return *surface_.Get([this] { return std::optional<SurfaceProperties>(AnalyzeOwnSurface({})); });
}

const FeatureCloud* Target::features(const StopCheck& should_stop) const {
  return features_.Get([&] { return BuildFeatures(should_stop); });
}

std::uint64_t Target::EstimateBytes(std::uint64_t point_count, bool has_normals,
                                    const std::optional<PinholeIntrinsics>& intrinsics) {
  const std::uint64_t per_point = sizeof(Vec3) * (has_normals ? 3 : 2) + sizeof(double) + 1;
  return point_count * per_point + (intrinsics ? GridBytes(*intrinsics) : 0);
}

std::size_t Target::MemoryBytes() const {
  const SurfaceProperties* surface = surface_.IfBuilt();
  const FeatureCloud* features = features_.IfBuilt();
  return cloud_.points.capacity() * sizeof(Vec3) + cloud_.normals.capacity() * sizeof(Vec3) +
         (surface ? surface->normals.capacity() * sizeof(Vec3) +
                        surface->curvature.capacity() * sizeof(double) + surface->valid.capacity()
                  : 0) +
         tree_->MemoryBytes() + (grid_ ? grid_->MemoryBytes() : 0) +
         (mls_patches_ ? mls_patches_->MemoryBytes() : 0) +
         (features ? features->MemoryBytes() : 0) + voxel_cloud_.MemoryBytes() +
         (sensor_view_ ? sensor_view_->MemoryBytes() : 0) + sizeof(Target);
}

}  // namespace mlsreg
