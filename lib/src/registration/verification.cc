#include "mlsreg/registration/verification.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_format.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/geometry/weighted_covariance.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

double Squared(double x) { return x * x; }

// The RMS of a unit Gaussian cut at +-3.
constexpr double kTruncatedGaussianRms = 0.9733;
// A voxel this planar (1 - 3 surface variation) counts its spread as noise.
constexpr double kFlatVoxelPlanarity = 0.9;
// The local surface is fitted to this many target samples; they span a plane when their middle
// principal spread is at least this share of the largest.
constexpr std::size_t kSurfaceNeighbors = 12;
constexpr double kMinPlaneSpread = 0.05;

// Where a moved sample meets the target's surface, and the noise expected there.
struct SurfaceHit {
  double distance = 0.0;  // to the surface (absolute)
  // The local plane's normal and the signed distance across it (zero normal: no plane there).
  Vec3 normal = Vec3::Zero();
  double across = 0.0;
  // The target's noise there: its spread about its voxel's plane where that is flat.
  double local_noise = 0.0;
};

// The target's surface near `x`: its MLS projection where the patches reach; else the plane
// through the centroid of its kSurfaceNeighbors samples nearest `x` (noise averages out over
// them, where the nearest sample alone is biased toward `x`), with their normal when they span a
// plane and their voxel's otherwise (on a LiDAR's far rings the nearest samples lie along one
// ring, a line whose plane is anyone's guess).
SurfaceHit HitSurface(const Target& target, const Vec3& x) {
  const VoxelCloud& voxels = target.voxel_cloud();
  const std::uint32_t voxel = voxels.tree->Nearest(x).index;
  SurfaceHit hit;
  // Only a flat voxel's spread is noise; elsewhere it is mostly shape.
  if (voxels.valid[voxel] && voxels.planarity[voxel] >= kFlatVoxelPlanarity) {
    hit.local_noise = voxels.spread[voxel];
  }
  if (const MlsPatches* patches = target.mls_patches(); patches != nullptr) {
    const MlsProjection p = patches->Project(x, /*seed_far_queries=*/false);
    if (p.status == ProjectionStatus::kOk) {
      hit.normal = p.normal;
      hit.across = (x - p.point).dot(p.normal);
      hit.distance = (x - p.point).norm();
      return hit;
    }
  }
  std::uint32_t index[kSurfaceNeighbors];
  double d2[kSurfaceNeighbors];
  const std::size_t found = target.tree().Knn(x, kSurfaceNeighbors, index, d2);
  WeightedCovariance covariance(x);
  for (std::size_t j = 0; j < found; ++j) covariance.Add(target.points()[index[j]], 1.0);
  LocalFrame frame;
  const bool spans_plane =
      covariance.Finalize(frame) && frame.eigenvalues[1] >= kMinPlaneSpread * frame.eigenvalues[2];
  Vec3 normal;
  if (spans_plane) {
    normal = frame.normal;
  } else if (voxels.valid[voxel]) {
    normal = voxels.normals[voxel];
  } else {
    hit.distance = std::sqrt(d2[0]);
    return hit;
  }
  const Vec3 centre = spans_plane ? frame.mean : target.points()[index[0]];
  // Along the plane, a sample is only as close as the data allow: the plane says little about a
  // point beyond the neighbourhood it was fitted to.
  const Vec3 offset = x - centre;
  const double reach = found > 1 ? std::sqrt(d2[found - 1]) : 0.0;
  const double along = (offset - offset.dot(normal) * normal).norm();
  hit.normal = normal;
  hit.across = offset.dot(normal);
  const double across = std::abs(hit.across);
  hit.distance = along <= reach ? across : std::hypot(across, along - reach);
  return hit;
}

// An inlier's residual across the target's plane where it lands.
struct Pull {
  Vec3 x;  // the moved sample
  Vec3 normal;
  double across;  // signed distance along `normal`
};

// How much of the inliers' residuals one small rigid motion would remove: the least-squares
// point-to-plane step from the pose, and the share of the residuals' sum of squares it explains.
// At a right pose the residuals are noise, and a rigid motion explains about 6 / inliers of them;
// a pose turned or slid off the truth leaves residuals that one motion explains well.
// The point-to-plane step (rotation about the centre in units of the lever, then translation);
// a direction the planes barely constrain (along a road) gets a small ridge instead of an
// arbitrary step.
Vector6 SolveStep(const Matrix6& normal_matrix, const Vector6& gradient) {
  const double ridge = 1e-6 * normal_matrix.trace();
  return (normal_matrix + ridge * Matrix6::Identity()).ldlt().solve(-gradient);
}

void MeasurePull(std::span<const Pull> pulls, const Vec3& centre, double lever,
                 VerificationScore& score) {
  if (pulls.size() < 12) return;
  Matrix6 normal_matrix = Matrix6::Zero();
  Vector6 gradient = Vector6::Zero();
  double sum_squared = 0.0;
  for (const Pull& p : pulls) {
    Vector6 j;
    j.head<3>() = (p.x - centre).cross(p.normal) / lever;
    j.tail<3>() = p.normal;
    normal_matrix.noalias() += j * j.transpose();
    gradient += j * p.across;
    sum_squared += p.across * p.across;
  }
  if (!(sum_squared > 0.0)) return;
  const Vector6 step = SolveStep(normal_matrix, gradient);
  score.pull_fraction = std::clamp(-gradient.dot(step) / sum_squared, 0.0, 1.0);
  score.pull_rotation_deg = step.head<3>().norm() / lever * 180.0 / M_PI;
  score.pull_translation = step.tail<3>().norm();
  double displacement_squared = 0.0;
  for (const Pull& p : pulls) {
    displacement_squared +=
        ((step.head<3>() / lever).cross(p.x - centre) + step.tail<3>()).squaredNorm();
  }
  score.pull_displacement = std::sqrt(displacement_squared / pulls.size());
}

// Where the data move the pose: up to kSettleSteps point-to-plane steps on the target's
// surface from it, each over the samples inside their band at the moved pose. Returns the RMS
// distance the samples in `moved` (the inliers at the pose) travel. A right pose moves by its
// registration precision; a pose turned or slid off the truth moves back toward it.
constexpr int kSettleSteps = 6;
template <typename BandOf>
double SettleDisplacement(const Target& target, std::span<const Vec3> points,
                          std::span<const std::uint8_t> state, const RigidTransform& pose,
                          const Vec3& centre, double lever, double coverage,
                          const BandOf& band_of) {
  const VoxelCloud& voxels = target.voxel_cloud();
  RigidTransform current = pose;
  for (int step_index = 0; step_index < kSettleSteps; ++step_index) {
    Matrix6 normal_matrix = Matrix6::Zero();
    Vector6 gradient = Vector6::Zero();
    int used = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec3 x = current * points[i];
      if (voxels.tree->Nearest(x).distance_squared > coverage * coverage) continue;
      const SurfaceHit hit = HitSurface(target, x);
      if (hit.distance > band_of(hit) || !(hit.normal.squaredNorm() > 0.0)) continue;
      Vector6 j;
      j.head<3>() = (x - centre).cross(hit.normal) / lever;
      j.tail<3>() = hit.normal;
      normal_matrix.noalias() += j * j.transpose();
      gradient += j * hit.across;
      ++used;
    }
    if (used < 12) break;
    const Vector6 step = SolveStep(normal_matrix, gradient);
    const Vec3 omega = step.head<3>() / lever;
    RigidTransform increment = RigidTransform::Identity();
    increment.linear() = ExpSo3(omega);
    increment.translation() = centre - increment.linear() * centre + step.tail<3>();
    current = increment * current;
    if (step.norm() < 1e-9 * lever) break;
  }
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (state[i] != 2) continue;
    sum += (current * points[i] - pose * points[i]).squaredNorm();
    ++count;
  }
  return count > 0 ? std::sqrt(sum / count) : 0.0;
}

// `floor` is the smallest band (one median spacing): a pose the data would move by less than
// that is never pulled, however significant the pull (clean data pull every imprecise pose).
Verdict Judge(const VerificationScore& s, bool unconstrained, const VerificationOptions& o,
              double rms_per_band, double floor) {
  if (s.covered < o.min_covered_samples) return Verdict::kTooLittleOverlap;
  if (s.inlier_fraction < o.min_inlier_fraction ||
      s.explained_fraction < o.min_explained_fraction) {
    return Verdict::kLowAgreement;
  }
  if (rms_per_band > o.max_rms_per_band) return Verdict::kDiffuseResiduals;
  const double settle_bound =
      std::max(o.max_settle_sigmas * s.inlier_distance / o.band_per_noise, floor);
  if (s.settle_displacement > settle_bound ||
      (s.pull_fraction > o.max_pull_fraction && s.settle_displacement > floor)) {
    return Verdict::kPulled;
  }
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
      {static_cast<int>(Verdict::kPulled), "pulled", "PULLED"},
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

VerificationScore VerifyAlignment(const Target& target, const VoxelCloud& samples,
                                  const Matrix4& transform, const NoiseLevels& noise,
                                  const VerificationOptions& options) {
  const std::vector<Vec3>& points = samples.points;
  const std::vector<Vec3>& normals = samples.normals;
  const double d = target.sampling_distance();
  const VoxelCloud& voxels = target.voxel_cloud();
  const double floor = options.min_band_spacings * target.scales().median_spacing;
  VerificationScore score;
  score.noise = std::hypot(noise.target, noise.source);
  const double band = std::max(options.band_per_noise * score.noise, floor);
  const double coverage = options.coverage_voxels * voxels.voxel + band;
  const RigidTransform pose(Orthonormalize(transform));
  score.inlier_distance = band;
  score.inlier_distance_d = band / d;
  score.samples = static_cast<int>(points.size());

  // The band where a sample lands: the residual expected there from the target's noise (its own
  // spread there when larger: far from a LiDAR) and the source's. The band is generous on
  // purpose: it separates the overlap from chance; the settling below judges how precisely the
  // pose sits.
  const auto band_of = [&](const SurfaceHit& hit) {
    const double sigma = std::hypot(std::max(noise.target, hit.local_noise), noise.source);
    return std::max(options.band_per_noise * sigma, floor);
  };

  // Pass 1: coverage and agreement, and the covered samples' centre.
  std::vector<std::uint8_t> state(points.size(), 0);  // 1 covered, 2 inlier
  std::vector<Pull> pulls;  // the inliers' residuals across the target's local planes
  pulls.reserve(points.size());
  double sum_squared = 0.0, sum_normalised = 0.0, sum_band = 0.0;
  Vec3 centre = Vec3::Zero();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 x = pose * points[i];
    if (voxels.tree->Nearest(x).distance_squared > coverage * coverage) continue;
    state[i] = 1;
    ++score.covered;
    centre += x;
    const SurfaceHit hit = HitSurface(target, x);
    const double local_band = band_of(hit);
    if (hit.distance > local_band) continue;
    state[i] = 2;
    ++score.inliers;
    sum_squared += hit.distance * hit.distance;
    sum_normalised += Squared(hit.distance / local_band);
    sum_band += local_band;
    if (hit.normal.squaredNorm() > 0.0) pulls.push_back({x, hit.normal, hit.across});
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
    score.residual_scale = rms_per_band * options.band_per_noise / kTruncatedGaussianRms;
    score.inlier_distance = sum_band / score.inliers;  // the mean band of the inliers
    score.inlier_distance_d = score.inlier_distance / d;
  }

  // Pass 2: the six directions of motion and the samples each one moves.
  double radius_squared = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (state[i]) radius_squared += (pose * points[i] - centre).squaredNorm();
  }
  const double lever = score.covered > 0 ? std::sqrt(radius_squared / score.covered) : 1.0;
  MeasurePull(pulls, centre, lever, score);
  if (score.inliers > 0) {
    score.settle_displacement =
        SettleDisplacement(target, points, state, pose, centre, lever, coverage, band_of);
  }
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
  score.verdict = Judge(score, unconstrained, options, rms_per_band, floor);
  return score;
}

VerificationScore VerifyPose(const Target& target, const PointCloud& source,
                             const Matrix4& transform, double source_noise_d, int threads) {
  const double d = target.sampling_distance();
  const VoxelCloud samples =
      BuildVoxelCloud(source.points, target.voxel_cloud().voxel, source.viewpoint, threads);
  return VerifyAlignment(target, samples, transform,
                         {target.noise().sigma_d * d, source_noise_d * d});
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
