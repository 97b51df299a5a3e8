#include "mlsreg/registration/verification.h"

#include <algorithm>
#include <cmath>

#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {

VerificationScore VerifyAlignment(const Target& target, const std::vector<Vec3>& points,
                                  const std::vector<Vec3>& normals, bool oriented,
                                  const Matrix4& transform, double noise_d,
                                  const VerificationOptions& options) {
  const double d = target.sampling_distance();
  const double limit =
      std::max(options.inlier_distance_d, options.inlier_noise_factor * noise_d) * d;
  const bool signed_normals = oriented && target.surface().oriented;
  const RigidTransform pose(Orthonormalize(transform));
  const MlsPatches* patches = target.mls_patches();
  VerificationScore score;
  score.inlier_distance_d = limit / d;
  score.samples = static_cast<int>(points.size());
  double sum_squared = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 x = pose * points[i];
    const Vec3 n = pose.linear() * normals[i];
    Vec3 foot, surface_normal;
    if (patches) {
      const MlsProjection p = patches->Project(x, /*seed_far_queries=*/false);
      if (p.status != ProjectionStatus::kOk) continue;
      foot = p.point;
      surface_normal = p.normal;
    } else {
      const Neighbor nearest = target.tree().Nearest(x);
      foot = target.points()[nearest.index];
      surface_normal = target.surface().normals[nearest.index];
    }
    const double distance_squared = (x - foot).squaredNorm();
    if (distance_squared > limit * limit) continue;
    const double dot = n.dot(surface_normal);
    if ((signed_normals ? dot : std::abs(dot)) < options.min_normal_dot) continue;
    ++score.inliers;
    sum_squared += distance_squared;
  }
  if (score.samples > 0) score.inlier_fraction = double(score.inliers) / score.samples;
  if (score.inliers > 0) score.rmse_d = std::sqrt(sum_squared / score.inliers) / d;
  return score;
}

std::vector<double> DistancesToMlsSurface(const Target& target, const std::vector<Vec3>& points) {
  std::vector<double> out(points.size());
  const MlsPatches* patches = target.mls_patches();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (patches) {
      const MlsProjection p = patches->Project(points[i], /*seed_far_queries=*/false);
      if (p.status == ProjectionStatus::kOk) {
        out[i] = (points[i] - p.point).norm();
        continue;
      }
    }
    out[i] = std::sqrt(target.tree().Nearest(points[i]).distance_squared);
  }
  return out;
}

bool IsVerified(const VerificationScore& score, double min_inlier_fraction) {
  return score.inliers > 0 && score.inlier_fraction >= min_inlier_fraction &&
         score.rmse_d <= kMaxVerifiedRmsePerInlierDistance * score.inlier_distance_d;
}

}  // namespace mlsreg
