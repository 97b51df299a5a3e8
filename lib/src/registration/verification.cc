#include "mlsreg/registration/verification.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_format.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

double Squared(double x) { return x * x; }

// A voxel this planar (1 - 3 surface variation) counts its spread as noise.
constexpr double kFlatVoxelPlanarity = 0.9;
// The plane of the nearest sample reaches as far along itself as its kReachNeighbors-th neighbour.
constexpr std::size_t kReachNeighbors = 8;

// Where a moved sample meets the target's surface, and the noise expected there.
struct SurfaceHit {
  double distance = 0.0;     // to the surface (absolute)
  double local_noise = 0.0;  // the spread of the target's samples around its voxel's plane
};

SurfaceHit HitSurface(const Target& target, const Vec3& x) {
  const VoxelCloud& voxels = target.voxel_cloud();
  const std::uint32_t voxel = voxels.tree->Nearest(x).index;
  SurfaceHit hit;
  // Only a flat voxel's spread is noise; elsewhere it is mostly shape.
  if (voxels.valid[voxel] && voxels.planarity[voxel] >= kFlatVoxelPlanarity) {
    hit.local_noise = voxels.spread[voxel];
  }
  // The plane of the nearest sample, with its voxel's normal: a plane fitted over the voxel's
  // neighbours, which a LiDAR's rings cannot tilt (a small neighbourhood there is one ring, a
  // line whose plane is anyone's guess), or the sample's own where the voxel has none.
  const Neighbor nearest = target.tree().Nearest(x);
  const Vec3 offset = x - target.points()[nearest.index];
  const SurfaceProperties& surface = target.surface();
  Vec3 normal;
  if (voxels.valid[voxel]) {
    normal = voxels.normals[voxel];
  } else if (surface.valid[nearest.index]) {
    normal = surface.normals[nearest.index];
  } else {
    hit.distance = offset.norm();
    return hit;
  }
  // Along the plane, a sample is only as close as the data allow: the plane of a sample says
  // little about a point beyond its neighbourhood (kReachNeighbors of them: across a LiDAR's
  // rings, not just along one).
  std::uint32_t index[kReachNeighbors];
  double d2[kReachNeighbors];
  const std::size_t found =
      target.tree().Knn(target.points()[nearest.index], kReachNeighbors, index, d2);
  const double reach = found > 1 ? std::sqrt(d2[found - 1]) : 0.0;
  const double along = (offset - offset.dot(normal) * normal).norm();
  const double across = std::abs(offset.dot(normal));
  hit.distance = along <= reach ? across : std::hypot(across, along - reach);
  return hit;
}

Verdict Judge(const VerificationScore& s, bool unconstrained, const VerificationOptions& o,
              double rms_per_band) {
  if (s.covered < o.min_covered_samples) return Verdict::kTooLittleOverlap;
  if (s.inlier_fraction < o.min_inlier_fraction ||
      s.explained_fraction < o.min_explained_fraction) {
    return Verdict::kLowAgreement;
  }
  if (rms_per_band > o.max_rms_per_band) return Verdict::kDiffuseResiduals;
  if (unconstrained) return Verdict::kUnconstrained;
  if (s.worst_direction_fraction < o.min_direction_ratio * s.inlier_fraction) {
    return Verdict::kDirectionDisagrees;
  }
  return Verdict::kVerified;
}

}  // namespace

const EnumNames& VerdictNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(Verdict::kVerified), "verified", "VERIFIED"},
      {static_cast<int>(Verdict::kTooLittleOverlap), "too_little_overlap", "TOO_LITTLE_OVERLAP"},
      {static_cast<int>(Verdict::kLowAgreement), "low_agreement", "LOW_AGREEMENT"},
      {static_cast<int>(Verdict::kDiffuseResiduals), "diffuse_residuals", "DIFFUSE_RESIDUALS"},
      {static_cast<int>(Verdict::kDirectionDisagrees), "direction_disagrees",
       "DIRECTION_DISAGREES"},
      {static_cast<int>(Verdict::kUnconstrained), "unconstrained", "UNCONSTRAINED"},
  };
  static constexpr EnumNames kNames{"Verdict", "VERDICT_", kValues};
  return kNames;
}

std::string_view VerdictName(Verdict verdict) { return NameOf(VerdictNames(), verdict); }

std::string VerificationScore::WorstDirectionText() const {
  const Vec3 rotation = worst_direction.head<3>(), translation = worst_direction.tail<3>();
  const bool rotates = rotation.squaredNorm() > translation.squaredNorm();
  const Vec3 axis = (rotates ? rotation : translation).normalized();
  return absl::StrFormat("%s (%.2f, %.2f, %.2f)", rotates ? "rotation about" : "translation along",
                         axis.x(), axis.y(), axis.z());
}

double CombinedNoise(double target_sigma, double source_sigma) {
  return std::hypot(target_sigma, source_sigma);
}

VerificationScore VerifyAlignment(const Target& target, std::span<const Vec3> points,
                                  std::span<const Vec3> normals, const Matrix4& transform,
                                  double noise, const VerificationOptions& options) {
  const double d = target.sampling_distance();
  const VoxelCloud& voxels = target.voxel_cloud();
  const double floor = options.min_band_spacings * target.scales().median_spacing;
  const double band = std::max(options.band_per_noise * noise, floor);
  const double coverage = options.coverage_voxels * voxels.voxel + band;
  const RigidTransform pose(Orthonormalize(transform));
  VerificationScore score;
  score.inlier_distance = band;
  score.inlier_distance_d = band / d;
  score.samples = static_cast<int>(points.size());

  // Pass 1: coverage and agreement, and the covered samples' centre.
  std::vector<std::uint8_t> state(points.size(), 0);  // 1 covered, 2 inlier
  double sum_squared = 0.0, sum_normalised = 0.0, sum_band = 0.0;
  Vec3 centre = Vec3::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 x = pose * points[i];
    if (voxels.tree->Nearest(x).distance_squared > coverage * coverage) continue;
    state[i] = 1;
    ++score.covered;
    centre += x;
    const SurfaceHit hit = HitSurface(target, x);
    // The band where the sample lands: the clouds' noise, or the target's own spread there when
    // larger (far from a LiDAR, in clutter), counted for both clouds.
    const double sigma = std::max(noise, std::sqrt(2.0) * hit.local_noise);
    const double local_band = std::max(options.band_per_noise * sigma, floor);
    if (hit.distance > local_band) continue;
    state[i] = 2;
    ++score.inliers;
    sum_squared += hit.distance * hit.distance;
    sum_normalised += Squared(hit.distance / local_band);
    sum_band += local_band;
  }
  if (score.covered > 0) {
    score.inlier_fraction = static_cast<double>(score.inliers) / score.covered;
    centre /= score.covered;
  }
  if (score.samples > 0)
    score.explained_fraction = static_cast<double>(score.inliers) / score.samples;
  double rms_per_band = 1.0;
  if (score.inliers > 0) {
    score.rmse_d = std::sqrt(sum_squared / score.inliers) / d;
    rms_per_band = std::sqrt(sum_normalised / score.inliers);
    score.inlier_distance = sum_band / score.inliers;  // the mean band of the inliers
    score.inlier_distance_d = score.inlier_distance / d;
  }

  // Pass 2: the six directions of motion and the samples each one moves.
  double radius_squared = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (state[i]) radius_squared += (pose * points[i] - centre).squaredNorm();
  }
  const double lever = score.covered > 0 ? std::sqrt(radius_squared / score.covered) : 1.0;
  std::vector<Vector6> jacobians(points.size(), Vector6::Zero());
  Matrix6 information = Matrix6::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!state[i] || !(normals[i].squaredNorm() > 0.0)) continue;
    const Vec3 x = pose * points[i] - centre;
    const Vec3 n = pose.linear() * normals[i];
    jacobians[i].head<3>() = x.cross(n) / lever;
    jacobians[i].tail<3>() = n;
    information.noalias() += jacobians[i] * jacobians[i].transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6> solver(information);
  // Each direction: how strongly the samples constrain it (its eigenvalue per covered sample:
  // the mean squared residual a unit motion along it causes), and how many of the samples that
  // constrain it most (at least half the top percentile's sensitivity) agree.
  struct Direction {
    Vector6 axis;
    double strength = 0.0;
    int constraining = 0;
    double fraction = 0.0;
  };
  std::vector<Direction> directions;
  std::vector<double> sensitivity;
  sensitivity.reserve(points.size());
  for (int k = 0; k < 6 && solver.info() == Eigen::Success && score.covered > 0; ++k) {
    Direction direction{solver.eigenvectors().col(k)};
    direction.strength = std::max(0.0, solver.eigenvalues()[k]) / score.covered;
    sensitivity.clear();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (state[i]) sensitivity.push_back(std::abs(jacobians[i].dot(direction.axis)));
    }
    const auto top =
        sensitivity.begin() + static_cast<std::ptrdiff_t>(0.99 * (sensitivity.size() - 1));
    std::nth_element(sensitivity.begin(), top, sensitivity.end());
    const double threshold = options.direction_sensitivity * *top;
    int agreeing = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!state[i] || !(std::abs(jacobians[i].dot(direction.axis)) >= threshold)) continue;
      ++direction.constraining;
      agreeing += state[i] == 2;
    }
    if (direction.constraining > 0) {
      direction.fraction = static_cast<double>(agreeing) / direction.constraining;
    }
    directions.push_back(direction);
  }
  // The weakest direction when the data barely constrain it, else the one whose samples agree
  // least.
  bool unconstrained = false;
  if (!directions.empty()) {
    auto worst = std::min_element(
        directions.begin(), directions.end(),
        [](const Direction& a, const Direction& b) { return a.strength < b.strength; });
    unconstrained = worst->strength < options.min_direction_strength;
    if (!unconstrained) {
      worst = std::min_element(
          directions.begin(), directions.end(),
          [](const Direction& a, const Direction& b) { return a.fraction < b.fraction; });
    }
    score.worst_direction = worst->axis;
    score.worst_direction_samples = worst->constraining;
    score.worst_direction_fraction = worst->fraction;
    score.worst_direction_strength = worst->strength;
  }
  score.verdict = Judge(score, unconstrained, options, rms_per_band);
  return score;
}

VerificationScore VerifyPose(const Target& target, const PointCloud& source,
                             const Matrix4& transform, double source_noise_d, int threads) {
  const double d = target.sampling_distance();
  const VoxelCloud samples =
      BuildVoxelCloud(source.points, target.voxel_cloud().voxel, source.viewpoint, threads);
  return VerifyAlignment(target, samples.points, samples.normals, transform,
                         CombinedNoise(target.noise().sigma_d * d, source_noise_d * d));
}

VerificationScore VerifyPose(const Target& target, const PointCloud& source,
                             const Matrix4& transform, int threads) {
  const KdTree tree(source.points);
  const NoiseEstimate noise =
      EstimateNoise(source.points, tree, target.sampling_distance(), {}, {}, {}, threads);
  return VerifyPose(target, source, transform, noise.sigma_d, threads);
}

bool BetterScore(const VerificationScore& a, const VerificationScore& b) {
  if (a.verified() != b.verified()) return a.verified();
  // Poses that explain the same samples to within 1 % are the same answer: neither is better,
  // so the one found first stays (a stable order does not flip on the last bit).
  const int margin = std::max(1, std::max(a.inliers, b.inliers) / 100);
  return a.inliers >= b.inliers + margin;
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

}  // namespace mlsreg
