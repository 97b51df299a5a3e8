#include "mlsreg/multiview/merged_cloud.h"

#include <chrono>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "mlsreg/geometry/mls_projector.h"
#include "mlsreg/geometry/mls_radius.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg {

PointCloud MergeScans(const std::vector<PointCloud>& scans, const std::vector<Matrix4>& poses) {
  PointCloud merged;
  bool normals = !scans.empty();
  for (const PointCloud& s : scans) normals = normals && s.has_normals();
  for (std::size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const Eigen::Matrix3d rotation = poses[i].topLeftCorner<3, 3>();
    const Vec3 translation = poses[i].topRightCorner<3, 1>();
    for (std::size_t k = 0; k < scans[i].size(); ++k) {
      merged.points.push_back(rotation * scans[i].points[k] + translation);
      if (normals) merged.normals.push_back(rotation * scans[i].normals[k]);
    }
  }
  return merged;
}

absl::StatusOr<ResampledCloud> ResampleOnMlsSurface(const PointCloud& merged, double d,
                                                    const SurfaceResampling& options,
                                                    const StopCheck& should_stop) {
  const auto start = std::chrono::steady_clock::now();
  if (!(d > 0.0) || !std::isfinite(d)) {
    return absl::InvalidArgumentError("d: the sampling distance must be positive");
  }
  // Lengths in the clouds' units are checked as what they are in the scans' d.
  const double spacing_d = options.spacing.InD(d), radius_d = options.radius.InD(d);
  if (!(spacing_d > 0.0 && spacing_d <= 100.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("spacing_d: must be in (0, 100]",
                     options.spacing.absolute ? absl::StrCat(", is ", spacing_d, " d") : ""));
  }
  if (!(radius_d >= 0.0 && radius_d <= 100.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("radius_d: must be in [0, 100] (0: automatic)",
                     options.radius.absolute ? absl::StrCat(", is ", radius_d, " d") : ""));
  }
  if (options.threads < 1) return absl::InvalidArgumentError("threads: must be >= 1");
  // Index and noise of the merged cloud (its patches and features are never used).
  TargetOptions target_options;
  target_options.threads = options.threads;
  auto built = Target::Build(merged, target_options, should_stop);
  if (!built.ok()) {
    return absl::Status(built.status().code(),
                        absl::StrCat("merged cloud: ", built.status().message()));
  }
  const Target& surface = **built;

  ResampledCloud out;
  // The noise is measured in the merged cloud's own (denser) d; the radius rule speaks of the
  // scans' d.
  out.noise_sigma_d = surface.noise().sigma_d * surface.sampling_distance() / d;
  out.radius_d = radius_d > 0.0 ? radius_d : AutoMlsRadiusD(out.noise_sigma_d);
  MlsOptions mls;
  mls.radius = out.radius_d * d;
  mls.search_margin = 0.25;
  const MlsProjector projector(surface.points(), surface.tree(), mls, surface.cloud().viewpoint);

  const std::vector<std::uint32_t> samples = VoxelRepresentatives(surface.points(), spacing_d * d);
  // The normal of the weighted PCA plane of the last fit: the cubic's gradient follows the noise.
  std::vector<MlsProjection> projected(samples.size());
  const bool finished = ProjectEach(
      projector, samples.size(), [&](std::size_t i) { return surface.points()[samples[i]]; },
      [&](std::size_t i, const MlsProjection& p, const MlsProjector::Workspace& workspace) {
        projected[i] = p;
        if (p.status != ProjectionStatus::kOk) return;
        const Vec3& plane = workspace.last_fit.frame.normal;
        projected[i].normal = plane.dot(p.normal) < 0.0 ? -plane : plane;
      },
      options.threads, should_stop);
  if (!finished) return absl::CancelledError("stopped while resampling the merged cloud");

  out.cloud.points.reserve(samples.size());
  out.cloud.normals.reserve(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const MlsProjection& p = projected[i];
    if (p.status != ProjectionStatus::kOk ||
        (p.point - surface.points()[samples[i]]).norm() > mls.radius) {
      ++out.dropped;
      continue;
    }
    out.cloud.points.push_back(p.point);
    out.cloud.normals.push_back(p.normal);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace mlsreg
