#include "mlsreg/registration/verification.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/str_format.h"
#include "gauss_newton_sums.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/core/parallel_sum.h"
#include "mlsreg/core/quantile.h"
#include "mlsreg/geometry/cloud_scales.h"
#include "mlsreg/geometry/neighbor_cache.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/geometry/weighted_covariance.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;
using internal::GaussNewtonSums;

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
  // Where they differ from `normal` and `across` (a patch on one scan line): the settling's.
  std::optional<Vec3> settle_normal;
  double settle_across = 0.0;
};

using SampleCaches = VerificationCaches::Sample;

// Where each sample landed in the last pass: the voxel coverage test, and the surface hit.
struct SampleHit {
  Vec3 x = Vec3::Zero();      // the sample under the pass's pose
  bool covered = false;       // a target voxel within the coverage distance
  bool hidden = false;        // not covered, where the target's sensor could not see
  bool seen_through = false;  // not hidden, where the target's sensor saw through it
  SurfaceHit hit;             // where it meets the surface (covered samples)
};

// The target's surface near `x`: its MLS projection where the patches reach; else the plane
// through the centroid of its kSurfaceNeighbors samples nearest `x` (noise averages out over
// them, where the nearest sample alone is biased toward `x`), with their normal when they span a
// plane and their voxel's otherwise (on a LiDAR's far rings the nearest samples lie along one
// ring, a line whose plane is anyone's guess).
// `voxel`: the target's voxel nearest `x` (the caller's coverage test found it); `caches`: the
// sample's.
SurfaceHit HitSurface(const Target& target, const Vec3& x, std::uint32_t voxel,
                      SampleCaches& caches) {
  const VoxelCloud& voxels = target.voxel_cloud();
  SurfaceHit hit;
  // Only a flat voxel's spread is noise; elsewhere it is mostly shape.
  if (voxels.valid[voxel] && voxels.planarity[voxel] >= kFlatVoxelPlanarity) {
    hit.local_noise = voxels.spread[voxel];
  }
  if (const MlsPatches* patches = target.mls_patches(); patches != nullptr) {
    const MlsProjection p = patches->ProjectForJudging(x, &caches.anchors);
    if (p.status == ProjectionStatus::kOk) {
      hit.normal = p.normal;
      hit.across = (x - p.point).dot(p.normal);
      hit.distance = (x - p.point).norm();
      // A patch fitted to one scan line lies in the beam's cone, whatever the surface does
      // above and below the ring (MlsPatches): the settling measures the sample along the
      // normal of its voxel instead, whose samples span the rings around.
      if (p.one_scan_line && voxels.valid[voxel]) {
        hit.settle_normal = voxels.normals[voxel];
        hit.settle_across = (x - p.point).dot(*hit.settle_normal);
      }
      return hit;
    }
  }
  std::uint32_t index[kSurfaceNeighbors];
  double d2[kSurfaceNeighbors];
  const std::size_t found =
      CachedKnn(target.tree(), target.points(), x, kSurfaceNeighbors, &caches.samples, index, d2);
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

// One sample under `pose`: its coverage and, when covered, where it meets the surface; with the
// target's sensor `view` (the first pass), also whether that sensor hides it or saw through it.
SampleHit HitSample(const Target& target, const Vec3& point, const RigidTransform& pose,
                    double coverage, const SensorView* view, SampleCaches& caches) {
  const VoxelCloud& voxels = target.voxel_cloud();
  SampleHit h;
  h.x = pose * point;
  const Neighbor voxel = CachedNearest(*voxels.tree, voxels.points, h.x, caches.voxels);
  h.covered = voxel.distance_squared <= coverage * coverage;
  if (view != nullptr) {
    h.hidden = !h.covered && view->Hides(h.x, coverage);
    h.seen_through = !h.hidden && view->SeesThrough(h.x, coverage);
  }
  if (h.covered) h.hit = HitSurface(target, h.x, voxel.index, caches);
  return h;
}

// Every sample under `pose`, in parallel (each with its own caches): the passes below then sum
// over the samples in fixed blocks (ParallelSum), so that the verdict is the same for any thread
// count.
void HitSamples(const Target& target, std::span<const Vec3> points, const RigidTransform& pose,
                double coverage, const SensorView* view, std::span<SampleCaches> caches,
                std::span<SampleHit> hits, int threads) {
  ParallelFor(
      points.size(), threads,
      [&](std::size_t begin, std::size_t end, int) {
        for (std::size_t i = begin; i < end; ++i) {
          hits[i] = HitSample(target, points[i], pose, coverage, view, caches[i]);
        }
      },
      64);
}

// An inlier's residual across the target's plane where it lands.
struct Pull {
  Vec3 x;  // the moved sample
  Vec3 normal;
  double across;  // signed distance along `normal`
};

// The point-to-plane step (rotation about the centre in units of the lever, then translation);
// a direction the planes barely constrain (along a road) gets a small ridge instead of an
// arbitrary step.
Vector6 SolveStep(const Matrix6& normal_matrix, const Vector6& gradient) {
  const double ridge = 1e-6 * normal_matrix.trace();
  return (normal_matrix + ridge * Matrix6::Identity()).ldlt().solve(-gradient);
}

// A light sum (a few flops a sample) goes on a second thread only above this many samples a
// thread: waking a worker costs tens of microseconds.
constexpr std::size_t kMinSumsPerThread = 4096;

// How a pull's residual across the target's plane changes under a step (rotation about `centre`
// in units of `lever`, then translation): residual + J . step.
Vector6 StepJacobian(const Pull& p, const Vec3& centre, double lever) {
  Vector6 j;
  j.head<3>() = (p.x - centre).cross(p.normal) / lever;
  j.tail<3>() = p.normal;
  return j;
}

// How much of the inliers' residuals one small rigid motion would remove: the least-squares
// point-to-plane step from the pose, and the share of the residuals' sum of squares it explains.
// At a right pose the residuals are noise, and a rigid motion explains about 6 / inliers of them;
// a pose turned or slid off the truth leaves residuals that one motion explains well.
// Returns the step (zero when there is none).
Vector6 MeasurePull(std::span<const Pull> pulls, const Vec3& centre, double lever, int threads,
                    VerificationScore& score) {
  if (pulls.size() < 12) return Vector6::Zero();
  std::vector<GaussNewtonSums> partials;
  const GaussNewtonSums sums = ParallelSum(
      pulls.size(), threads, partials,
      [&](std::size_t i, GaussNewtonSums& block) {
        const Pull& p = pulls[i];
        const Vector6 j = StepJacobian(p, centre, lever);
        block.h.noalias() += j * j.transpose();
        block.g += j * p.across;
        block.sum_squared += p.across * p.across;
      },
      [](GaussNewtonSums& total, const GaussNewtonSums& block) { total.Add(block); },
      kMinSumsPerThread);
  if (!(sums.sum_squared > 0.0)) return Vector6::Zero();
  const Vector6 step = SolveStep(sums.h, sums.g);
  score.pull_fraction = std::clamp(-sums.g.dot(step) / sums.sum_squared, 0.0, 1.0);
  score.pull_rotation_deg = step.head<3>().norm() / lever * 180.0 / M_PI;
  score.pull_translation = step.tail<3>().norm();
  std::vector<double> displacement_partials;
  const double displacement_squared = ParallelSum(
      pulls.size(), threads, displacement_partials,
      [&](std::size_t i, double& block) {
        block +=
            ((step.head<3>() / lever).cross(pulls[i].x - centre) + step.tail<3>()).squaredNorm();
      },
      [](double& total, double block) { total += block; }, kMinSumsPerThread);
  score.pull_displacement = std::sqrt(displacement_squared / pulls.size());
  return step;
}

// The residuals' shared part between neighbouring inliers: sqrt of the mean product of the
// signed residuals of pairs within `radius` (signs made consistent by their normals), or 0. The
// residuals are taken after the pull's `step`: what one rigid motion explains (an imprecise
// pose's smooth residual field) is the pull's to judge. Noise is independent from sample to
// sample and leaves about 0; a surface that is not the target's shape (another object) leaves
// residuals that neighbours share and no rigid motion removes.
// The same pairs give the spread of the point-to-plane gradient sum_i J_i r_i (J_i: StepJacobian)
// under residuals that neighbours share: sum_i J_i r_i (J_i r_i + sum_j J_j r_j)^T over each
// sample's neighbours j, the middle of a sandwich covariance (independent residuals leave the
// first term alone). J r does not depend on the normal's sign.
constexpr std::size_t kMinSharedResidualSamples = 12;  // fewer: no measure (and no covariance)
struct SharedResiduals {
  double coherent = 0.0;
  Matrix6 gradient_spread = Matrix6::Zero();  // symmetric
};
SharedResiduals MeasureSharedResiduals(std::span<const Pull> pulls, double radius,
                                       const Vec3& centre, double lever, const Vector6& step,
                                       int threads) {
  SharedResiduals out;
  if (pulls.size() < kMinSharedResidualSamples) return out;
  std::vector<Vec3> positions(pulls.size());
  std::vector<double> residuals(pulls.size());  // after the step
  ParallelFor(
      pulls.size(), threads,
      [&](std::size_t begin, std::size_t end, int) {
        for (std::size_t i = begin; i < end; ++i) {
          positions[i] = pulls[i].x;
          residuals[i] = pulls[i].across + StepJacobian(pulls[i], centre, lever).dot(step);
        }
      },
      kMinSumsPerThread);
  const auto gradient = [&](std::size_t i) -> Vector6 {  // J_i r_i
    return StepJacobian(pulls[i], centre, lever) * residuals[i];
  };
  const KdTree tree(positions, threads);
  constexpr int kNeighbours = 7;  // the sample itself and six others
  // Each sample's products with its neighbours, summed in fixed blocks of samples on the threads
  // (ParallelSum): the same value for any thread count.
  struct Sums {
    double products = 0.0;
    long pairs = 0;
    Matrix6 spread = Matrix6::Zero();
  };
  std::vector<Sums> partials;
  const Sums sums = ParallelSum(
      pulls.size(), threads, partials,
      [&](std::size_t i, Sums& block) {
        std::uint32_t index[kNeighbours];
        double distance_squared[kNeighbours];
        const std::size_t found = tree.Knn(pulls[i].x, kNeighbours, index, distance_squared);
        Vector6 neighbour_gradients = Vector6::Zero();
        for (std::size_t k = 0; k < found; ++k) {
          const std::uint32_t j = index[k];
          if (j == i || distance_squared[k] > radius * radius) continue;
          const double sign = pulls[i].normal.dot(pulls[j].normal) < 0.0 ? -1.0 : 1.0;
          block.products += residuals[i] * sign * residuals[j];
          neighbour_gradients += gradient(j);
          ++block.pairs;
        }
        const Vector6 own = gradient(i);
        block.spread.noalias() += own * (own + neighbour_gradients).transpose();
      },
      [](Sums& total, const Sums& block) {
        total.products += block.products;
        total.pairs += block.pairs;
        total.spread += block.spread;
      });
  out.coherent = sums.pairs > 0 ? std::sqrt(std::max(0.0, sums.products / sums.pairs)) : 0.0;
  out.gradient_spread = 0.5 * (sums.spread + sums.spread.transpose());
  return out;
}

// Where the data move the pose: up to kSettleSteps point-to-plane steps on the target's
// surface from it, each over the samples inside their band at the moved pose, ending early once
// a step moves the samples by less than `tolerance`. Returns the pose it stops at and the RMS
// distance the inliers at `pose` (state 2) travel to it. A right pose moves by its registration
// precision; a pose turned or slid off the truth moves back toward it. `hits` holds the samples
// at `pose` on entry (the first step starts from them).
// Samples whose patch lies on one scan line are measured along their voxel's normal
// (SurfaceHit::settle_normal) when they are a minority, at most kMaxOneScanLineShare of the
// samples in their band at `pose`: the far façades of a sparse sensor (16-beam tuning streets:
// 6-13 %), whose flat patches would walk the pose in pitch. Where they are many (64-beam
// corridors and an open road seen at grazing incidence: 25-37 %) the coarse voxel normals would
// blur the structure that fixes the slide along them (a corridor pose 0.49 m off then settled
// in place and verified), and every sample keeps its patch's normal.
constexpr int kSettleSteps = 6;
constexpr double kMaxOneScanLineShare = 0.2;
struct Settling {
  double displacement = 0.0;  // RMS, of the inliers at the pose
  Matrix4 pose = Matrix4::Identity();
  bool one_scan_lines_corrected = false;  // samples on one scan line took their voxel's normal
  double one_scan_line_share = 0.0;       // of the in-band samples at the pose
};
template <typename BandOf>
Settling Settle(const Target& target, std::span<const Vec3> points,
                std::span<const std::uint8_t> state, std::span<SampleCaches> caches,
                std::span<SampleHit> hits, int threads, const RigidTransform& pose,
                const Vec3& centre, double lever, double coverage, double tolerance,
                const BandOf& band_of) {
  // A sample the settling steps on: covered, within its band, with a surface normal.
  const auto settles = [&](const SampleHit& sample) {
    return sample.covered && sample.hit.distance <= band_of(sample.hit) &&
           sample.hit.normal.squaredNorm() > 0.0;
  };
  int in_band = 0, on_one_line = 0;
  for (const SampleHit& sample : hits) {
    if (!settles(sample)) continue;
    ++in_band;
    on_one_line += sample.hit.settle_normal.has_value();
  }
  Settling settling;
  settling.one_scan_line_share = in_band > 0 ? static_cast<double>(on_one_line) / in_band : 0.0;
  settling.one_scan_lines_corrected =
      on_one_line > 0 && settling.one_scan_line_share <= kMaxOneScanLineShare;
  RigidTransform current = pose;
  std::vector<GaussNewtonSums> partials;
  for (int step_index = 0; step_index < kSettleSteps; ++step_index) {
    // Each sample where the step before moved it (the first step: where `pose` put it), and its
    // terms of the step's normal equations, in fixed blocks on the threads.
    const GaussNewtonSums sums = ParallelSum(
        points.size(), threads, partials,
        [&](std::size_t i, GaussNewtonSums& block) {
          if (step_index > 0) {
            hits[i] = HitSample(target, points[i], current, coverage, nullptr, caches[i]);
          }
          const SampleHit& sample = hits[i];
          if (!settles(sample)) return;
          const SurfaceHit& hit = sample.hit;
          const bool corrected = settling.one_scan_lines_corrected && hit.settle_normal;
          const Vec3& normal = corrected ? *hit.settle_normal : hit.normal;
          Vector6 j;
          j.head<3>() = (sample.x - centre).cross(normal) / lever;
          j.tail<3>() = normal;
          block.h.noalias() += j * j.transpose();
          block.g += j * (corrected ? hit.settle_across : hit.across);
          ++block.matched;
        },
        [](GaussNewtonSums& total, const GaussNewtonSums& block) { total.Add(block); });
    if (sums.matched < 12) break;
    const Vector6 step = SolveStep(sums.h, sums.g);
    const Vec3 omega = step.head<3>() / lever;
    RigidTransform increment = RigidTransform::Identity();
    increment.linear() = ExpSo3(omega);
    increment.translation() = centre - increment.linear() * centre + step.tail<3>();
    current = increment * current;
    if (step.norm() < tolerance) break;  // rotations in units of the lever: a sample's motion
  }
  struct Displacement {
    double sum_squared = 0.0;
    int count = 0;
  };
  std::vector<Displacement> displacement_partials;
  const Displacement moved = ParallelSum(
      points.size(), threads, displacement_partials,
      [&](std::size_t i, Displacement& block) {
        if (state[i] != 2) return;
        block.sum_squared += (current * points[i] - pose * points[i]).squaredNorm();
        ++block.count;
      },
      [](Displacement& total, const Displacement& block) {
        total.sum_squared += block.sum_squared;
        total.count += block.count;
      },
      kMinSumsPerThread);
  settling.displacement = moved.count > 0 ? std::sqrt(moved.sum_squared / moved.count) : 0.0;
  settling.pose = current.matrix();
  return settling;
}

// The angle between a sample's normal and the target's where it lands beyond which the sample is
// taken to sit on a sharp edge (options.feature_angle_per_median times the agreeing samples'
// median angle, at least options.min_feature_angle_deg), in radians; `median_deg` gets the median.
double FeatureAngle(std::span<const Vec3> points, std::span<const Vec3> normals,
                    std::span<const Vec3> target_normals, std::span<const std::uint8_t> state,
                    const RigidTransform& pose, const VerificationOptions& options,
                    double& median_deg) {
  std::vector<double> angles;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (state[i] != 2 || !(normals[i].squaredNorm() > 0.0) ||
        !(target_normals[i].squaredNorm() > 0.0)) {
      continue;
    }
    const double cosine =
        std::abs((pose.linear() * normals[i]).normalized().dot(target_normals[i].normalized()));
    angles.push_back(std::acos(std::min(1.0, cosine)));
  }
  const double floor = options.min_feature_angle_deg * M_PI / 180.0;
  if (angles.empty()) return floor;
  const auto middle = angles.begin() + static_cast<std::ptrdiff_t>(angles.size() / 2);
  std::nth_element(angles.begin(), middle, angles.end());
  median_deg = *middle * 180.0 / M_PI;
  return std::max(options.feature_angle_per_median * *middle, floor);
}

// `floor` is the smallest band (one median spacing): a pose the data would move by less than
// that is never pulled, however significant the pull (clean data pull every imprecise pose).
// Whether the agreeing samples fix every direction of motion, and if not, whether the covered
// samples would (then the samples that would fix it disagree) or not even they.
enum class DirectionCheck { kFixed, kDisagrees, kUnconstrained };

// The settling beyond which a pose is pulled: max_settle_sigmas noise sigmas of the band, at
// least `floor`.
double SettleBound(const VerificationScore& s, const VerificationOptions& o, double floor) {
  return std::max(o.max_settle_sigmas * s.inlier_distance / o.band_per_noise, floor);
}

// The covariance of (lever * rotation vector, translation at the centre) as the sandwich
// A^-1 B A^-1: A the point-to-plane information, B the spread of the gradient (residuals times
// their Jacobians, with what neighbours share; its negative eigenvalues, sampling noise of the
// neighbours' products, dropped). For independent residuals of variance s^2, B = s^2 A and the
// covariance is s^2 A^-1. Empty unless A is positive definite (every direction constrained).
std::optional<Matrix6> CovarianceAtCentre(const Matrix6& information,
                                          const Matrix6& gradient_spread) {
  const Eigen::SelfAdjointEigenSolver<Matrix6> solver(information);
  if (solver.info() != Eigen::Success) return std::nullopt;
  const Vector6& eigenvalues = solver.eigenvalues();  // ascending
  if (!(eigenvalues[0] > 1e-12 * eigenvalues[5])) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Matrix6> spread(gradient_spread);
  if (spread.info() != Eigen::Success) return std::nullopt;
  const Matrix6 meat = spread.eigenvectors() * spread.eigenvalues().cwiseMax(0.0).asDiagonal() *
                       spread.eigenvectors().transpose();
  const Matrix6 inverse = solver.eigenvectors() * eigenvalues.cwiseInverse().asDiagonal() *
                          solver.eigenvectors().transpose();
  return Matrix6(inverse * meat * inverse);
}

// That covariance for (rotation vector, translation at the origin): a rotation omega about the
// centre c moves the origin by -omega x c = c x omega. Symmetric to the last bit.
Matrix6 CovarianceAtOrigin(const Matrix6& at_centre, const Vec3& c, double lever) {
  Eigen::Matrix3d cross;
  cross << 0.0, -c.z(), c.y(), c.z(), 0.0, -c.x(), -c.y(), c.x(), 0.0;
  Matrix6 map = Matrix6::Zero();
  map.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / lever;
  map.bottomLeftCorner<3, 3>() = cross / lever;
  map.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity();
  const Matrix6 covariance = map * at_centre * map.transpose();
  return 0.5 * (covariance + covariance.transpose());
}

Verdict Judge(const VerificationScore& s, DirectionCheck direction, const VerificationOptions& o,
              double rms_per_band, double floor) {
  if (s.covered < o.min_covered_samples) return Verdict::kTooLittleOverlap;
  if (s.inlier_fraction < o.min_inlier_fraction ||
      s.explained_fraction < o.min_explained_fraction) {
    return Verdict::kLowAgreement;
  }
  if (s.seen_through_fraction() > o.max_seen_through_fraction) return Verdict::kSeenThrough;
  if (s.sides_judged >= o.min_sides_judged &&
      s.seen_from_behind_fraction() > o.max_seen_from_behind_fraction) {
    return Verdict::kSeenFromBehind;
  }
  if (rms_per_band > o.max_rms_per_band) return Verdict::kDiffuseResiduals;
  if (s.coherent_residual > o.max_coherent_sigmas * s.inlier_distance / o.band_per_noise) {
    return Verdict::kCoherentResiduals;
  }
  if (s.settle_displacement > SettleBound(s, o, floor) ||
      (s.pull_fraction > o.max_pull_fraction && s.settle_displacement > floor)) {
    return Verdict::kPulled;
  }
  if (direction == DirectionCheck::kUnconstrained) return Verdict::kUnconstrained;
  if (direction == DirectionCheck::kDisagrees) return Verdict::kDirectionDisagrees;
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
      {static_cast<int>(Verdict::kCoherentResiduals), "coherent_residuals", "COHERENT_RESIDUALS"},
      {static_cast<int>(Verdict::kAmbiguous), "ambiguous", "AMBIGUOUS"},
      {static_cast<int>(Verdict::kSeenThrough), "seen_through", "SEEN_THROUGH"},
      {static_cast<int>(Verdict::kSeenFromBehind), "seen_from_behind", "SEEN_FROM_BEHIND"},
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
                                  const VerificationOptions& options, int threads,
                                  VerificationCaches* kept) {
  const std::vector<Vec3>& points = samples.points;
  const std::vector<Vec3>& normals = samples.normals;
  const double d = target.sampling_distance();
  const VoxelCloud& voxels = target.voxel_cloud();
  const double floor = options.min_band_spacings * target.scales().median_spacing;
  VerificationScore score;
  score.noise = std::hypot(noise.target, noise.source);
  const double band = std::max(options.band_per_noise * score.noise, floor);
  const double coverage = options.coverage_voxels * voxels.voxel + band;
  const RigidTransform pose(Orthonormalize(transform, Centroid(points)));
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
  std::vector<std::uint8_t> state(points.size(), 0);              // 1 covered, 2 inlier
  std::vector<Vec3> target_normals(points.size(), Vec3::Zero());  // where each sample lands
  VerificationCaches own;
  VerificationCaches& cached = kept != nullptr ? *kept : own;
  if (cached.target != &target || cached.samples.size() != points.size()) {
    cached.target = &target;
    cached.samples.assign(points.size(), SampleCaches{});
  }
  const std::span<SampleCaches> caches(cached.samples);
  std::vector<SampleHit> hits(points.size());
  const SensorView* view = target.sensor_view();
  HitSamples(target, points, pose, coverage, view, caches, hits, threads);
  // Both sensors, in the target's frame, when both are known.
  const bool judges_sides = view != nullptr && samples.sensor.has_value();
  const Vec3 target_sensor = judges_sides ? target.scales().sensor->position : Vec3::Zero();
  const Vec3 source_sensor = judges_sides ? Vec3(pose * *samples.sensor) : Vec3::Zero();
  const double min_side_sine = std::sin(options.min_side_view_angle_deg * M_PI / 180.0);
  struct AgreementSums {
    int hidden = 0, seen_through = 0, covered = 0, inliers = 0;
    int sides_judged = 0, seen_from_behind = 0;
    double sum_squared = 0.0, sum_normalised = 0.0, sum_band = 0.0;
    Vec3 covered_sum = Vec3::Zero();
    void Add(const AgreementSums& o) {
      hidden += o.hidden;
      seen_through += o.seen_through;
      covered += o.covered;
      inliers += o.inliers;
      sides_judged += o.sides_judged;
      seen_from_behind += o.seen_from_behind;
      sum_squared += o.sum_squared;
      sum_normalised += o.sum_normalised;
      sum_band += o.sum_band;
      covered_sum += o.covered_sum;
    }
  };
  std::vector<AgreementSums> agreement_partials;
  const AgreementSums agreement = ParallelSum(
      points.size(), threads, agreement_partials,
      [&](std::size_t i, AgreementSums& block) {
        const SampleHit& sample = hits[i];
        block.hidden += sample.hidden;
        block.seen_through += sample.seen_through;
        if (!sample.covered) return;
        const Vec3& x = sample.x;
        state[i] = 1;
        ++block.covered;
        block.covered_sum += x;
        const SurfaceHit& hit = sample.hit;
        target_normals[i] = hit.normal;
        const double local_band = band_of(hit);
        if (hit.distance > local_band) return;
        state[i] = 2;
        ++block.inliers;
        block.sum_squared += hit.distance * hit.distance;
        block.sum_normalised += Squared(hit.distance / local_band);
        block.sum_band += local_band;
        if (!judges_sides || !(hit.normal.squaredNorm() > 0.0)) return;
        const double target_side = hit.normal.dot(target_sensor - x);
        const double source_side = hit.normal.dot(source_sensor - x);
        if (std::abs(target_side) >
                std::max(local_band, min_side_sine * (target_sensor - x).norm()) &&
            std::abs(source_side) >
                std::max(local_band, min_side_sine * (source_sensor - x).norm())) {
          ++block.sides_judged;
          block.seen_from_behind += (target_side > 0.0) != (source_side > 0.0);
        }
      },
      [](AgreementSums& total, const AgreementSums& block) { total.Add(block); },
      kMinSumsPerThread);
  score.hidden = agreement.hidden;
  score.seen_through = agreement.seen_through;
  score.covered = agreement.covered;
  score.inliers = agreement.inliers;
  score.sides_judged = agreement.sides_judged;
  score.seen_from_behind = agreement.seen_from_behind;
  const double sum_squared = agreement.sum_squared;
  Vec3 centre = agreement.covered_sum;
  // The inliers' residuals across the target's local planes, in sample order.
  std::vector<Pull> pulls;
  pulls.reserve(score.inliers);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const SurfaceHit& hit = hits[i].hit;
    if (state[i] == 2 && hit.normal.squaredNorm() > 0.0) {
      pulls.push_back({hits[i].x, hit.normal, hit.across});
    }
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
    rms_per_band = std::sqrt(agreement.sum_normalised / score.inliers);
    score.residual_scale = rms_per_band * options.band_per_noise / kTruncatedGaussianRms;
    score.inlier_distance = agreement.sum_band / score.inliers;  // the mean band of the inliers
    score.inlier_distance_d = score.inlier_distance / d;
  }

  // Pass 2: the six directions of motion and the samples each one moves.
  std::vector<double> radius_partials;
  const double radius_squared = ParallelSum(
      points.size(), threads, radius_partials,
      [&](std::size_t i, double& block) {
        if (state[i]) block += (hits[i].x - centre).squaredNorm();
      },
      [](double& total, double block) { total += block; }, kMinSumsPerThread);
  const double lever = score.covered > 0 ? std::sqrt(radius_squared / score.covered) : 1.0;
  score.direction_centre = centre;
  score.direction_lever = lever;
  const Vector6 pull_step = MeasurePull(pulls, centre, lever, threads, score);
  const SharedResiduals shared =
      MeasureSharedResiduals(pulls, 2.0 * voxels.voxel, centre, lever, pull_step, threads);
  score.coherent_residual = shared.coherent;
  if (score.inliers > 0) {
    const double noise_sigma = score.inlier_distance / options.band_per_noise;
    const Settling settling =
        Settle(target, points, state, caches, hits, threads, pose, centre, lever, coverage,
               std::max(options.settle_tolerance_sigmas * noise_sigma, 1e-9 * lever), band_of);
    score.settle_displacement = settling.displacement;
    score.one_scan_line_share = settling.one_scan_line_share;
    if (settling.one_scan_lines_corrected) score.settled_pose = settling.pose;
  }
  // Pass 3: how precisely the agreeing samples fix each direction of motion. The point-to-plane
  // information of a set of samples along a direction (the sum of (J . axis)^2, rotations in
  // units of the lever) gives the pose's standard error there: residual RMS / sqrt(information).
  // Noisy normals tilt at random and would feign information along a bare road; the product of
  // the source's and the target's normals (independent noise) keeps only the shared shape:
  // sum (Js . axis)(Jt . axis), whose expectation is the noise-free information. It counts when
  // it stands out of its own noise by min_direction_z (a bare road gives about zero). The six
  // directions are the eigen-directions of the agreeing samples' information.
  // Samples on sharp edges (their two normals disagree beyond what noise gives) take no part.
  const double min_normal_cosine = std::cos(FeatureAngle(
      points, normals, target_normals, state, pose, options, score.normal_angle_median_deg));
  std::vector<Vector6> source_jacobians(points.size(), Vector6::Zero());
  std::vector<Vector6> target_jacobians(points.size(), Vector6::Zero());
  struct InformationSums {
    Matrix6 agreeing = Matrix6::Zero();
    Matrix6 shared = Matrix6::Zero();  // the agreeing samples' (source x target)
    int edge_samples = 0;
  };
  std::vector<InformationSums> information_partials;
  const InformationSums information = ParallelSum(
      points.size(), threads, information_partials,
      [&](std::size_t i, InformationSums& block) {
        if (!state[i] || !(normals[i].squaredNorm() > 0.0) ||
            !(target_normals[i].squaredNorm() > 0.0)) {
          return;
        }
        const Vec3 x = pose * points[i] - centre;
        const Vec3 n = pose.linear() * normals[i];
        const Vec3 m =
            n.dot(target_normals[i]) < 0.0 ? Vec3(-target_normals[i]) : target_normals[i];
        if (n.dot(m) < min_normal_cosine) {
          ++block.edge_samples;
          return;
        }
        source_jacobians[i] << x.cross(n) / lever, n;
        target_jacobians[i] << x.cross(m) / lever, m;
        if (state[i] == 2) {
          block.agreeing.noalias() += source_jacobians[i] * source_jacobians[i].transpose();
          block.shared.noalias() += source_jacobians[i] * target_jacobians[i].transpose();
        }
      },
      [](InformationSums& total, const InformationSums& block) {
        total.agreeing += block.agreeing;
        total.shared += block.shared;
        total.edge_samples += block.edge_samples;
      },
      kMinSumsPerThread);
  score.edge_samples = information.edge_samples;
  const Matrix6& agreeing_information = information.agreeing;
  const Matrix6& shared_information = information.shared;
  DirectionCheck direction = DirectionCheck::kFixed;
  const Eigen::SelfAdjointEigenSolver<Matrix6> solver(agreeing_information);
  if (solver.info() == Eigen::Success && score.inliers > 0) {
    const double rms = std::sqrt(sum_squared / score.inliers);
    const double bound =
        options.max_direction_error_sigmas * score.inlier_distance / options.band_per_noise;
    // Along `axis`, over the agreeing samples (or all covered ones): the standard error, and
    // whether the information is real (stands out of its scatter) and precise enough.
    struct AlongAxis {
      double information = 0.0, scatter = 0.0, strength = 0.0, error = 0.0;
      bool fixed = false;
    };
    std::vector<AlongAxis> along_partials;
    const auto along = [&](const Vector6& axis, bool agreeing_only) {
      AlongAxis a = ParallelSum(
          points.size(), threads, along_partials,
          [&](std::size_t i, AlongAxis& block) {
            if (state[i] == 0 || (agreeing_only && state[i] != 2)) return;
            const double s = source_jacobians[i].dot(axis), t = target_jacobians[i].dot(axis);
            block.information += s * t;
            // The noise of s * t: (s^2 - t^2) / 2 is s0 (e_s - e_t) for shared shape s0 and
            // noise e, and has the variance of s * t for pure noise.
            block.scatter += Squared(s * s - t * t) / 4.0;
            block.strength += s * s;
          },
          [](AlongAxis& total, const AlongAxis& block) {
            total.information += block.information;
            total.scatter += block.scatter;
            total.strength += block.strength;
          },
          kMinSumsPerThread);
      a.error = a.information > 0.0 ? rms / std::sqrt(a.information)
                                    : std::numeric_limits<double>::infinity();
      a.fixed = a.information > options.min_direction_z * std::sqrt(a.scatter) && a.error <= bound;
      return a;
    };
    // The least fixed of the six directions: the first that fails, else the least precise.
    int worst = 0;
    AlongAxis worst_along;
    for (int k = 0; k < 6; ++k) {
      const AlongAxis a = along(solver.eigenvectors().col(k), true);
      const bool worse = k == 0 || (!a.fixed && worst_along.fixed) ||
                         (a.fixed == worst_along.fixed && a.error > worst_along.error);
      if (worse) {
        worst = k;
        worst_along = a;
      }
    }
    const Vector6 axis = solver.eigenvectors().col(worst);
    score.worst_direction = axis;
    score.worst_direction_error = worst_along.error;
    const AlongAxis covered = along(axis, false);
    score.worst_direction_strength = covered.strength / score.covered;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> translations(
        agreeing_information.bottomRightCorner<3, 3>());
    if (translations.info() == Eigen::Success) {
      score.weakest_translation = translations.eigenvectors().col(0);
      Vector6 slide = Vector6::Zero();
      slide.tail<3>() = score.weakest_translation;
      score.weakest_translation_strength = along(slide, false).strength / score.covered;
    }
    if (!worst_along.fixed) {
      direction = covered.fixed ? DirectionCheck::kDisagrees : DirectionCheck::kUnconstrained;
    }
    // The evidence: the samples that constrain that direction most (at least
    // direction_sensitivity of the top percentile's sensitivity), and the share that agrees.
    std::vector<double> sensitivity;
    sensitivity.reserve(score.covered);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (state[i]) sensitivity.push_back(std::abs(source_jacobians[i].dot(axis)));
    }
    const double threshold = options.direction_sensitivity * QuantileInPlace(sensitivity, 0.99);
    int agreeing = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!state[i] || !(std::abs(source_jacobians[i].dot(axis)) >= threshold)) continue;
      ++score.worst_direction_samples;
      agreeing += state[i] == 2;
    }
    if (score.worst_direction_samples > 0) {
      score.worst_direction_fraction =
          static_cast<double>(agreeing) / score.worst_direction_samples;
    }
  }
  if (pulls.size() >= kMinSharedResidualSamples) {
    // Symmetric: the sum of s t^T has the expectation of the noise-free information.
    const std::optional<Matrix6> at_centre = CovarianceAtCentre(
        0.5 * (shared_information + shared_information.transpose()), shared.gradient_spread);
    if (at_centre) {
      score.pose_covariance = CovarianceAtOrigin(*at_centre, centre, lever);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> rotation(
          score.pose_covariance->topLeftCorner<3, 3>(), Eigen::EigenvaluesOnly);
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> translation(
          at_centre->bottomRightCorner<3, 3>(), Eigen::EigenvaluesOnly);
      score.pose_rotation_sigma_deg =
          std::sqrt(std::max(rotation.eigenvalues().maxCoeff(), 0.0)) * 180.0 / M_PI;
      score.pose_translation_sigma = std::sqrt(std::max(translation.eigenvalues().maxCoeff(), 0.0));
    }
  }
  score.verdict = Judge(score, direction, options, rms_per_band, floor);
  return score;
}

std::optional<Matrix6> PoseCovariance(const Matrix6& information, const Matrix6& gradient_spread,
                                      const Vec3& centre, double lever) {
  const std::optional<Matrix6> at_centre = CovarianceAtCentre(information, gradient_spread);
  if (!at_centre || !(lever > 0.0)) return std::nullopt;
  return CovarianceAtOrigin(*at_centre, centre, lever);
}

std::optional<Vec3> SourceSensor(const Target& target, const PointCloud& source, const KdTree& tree,
                                 int threads) {
  if (target.sensor_view() == nullptr) return std::nullopt;
  const std::optional<SensorFinding> sensor =
      FindScanSensor(source.points, tree, source.viewpoint, threads);
  if (!sensor) return std::nullopt;
  return sensor->position;
}

SourceMeasures MeasureSource(const Target& target, const PointCloud& source, int threads) {
  const KdTree tree(source.points, threads);
  return {
      EstimateNoise(source.points, tree, target.sampling_distance(), {}, {}, {}, threads).sigma_d,
      SourceSensor(target, source, tree, threads)};
}

VerificationScore VerifyPose(const Target& target, const PointCloud& source,
                             const Matrix4& transform, int threads) {
  const double d = target.sampling_distance();
  const SourceMeasures measured = MeasureSource(target, source, threads);
  VoxelCloud samples =
      BuildVoxelCloud(source.points, target.voxel_cloud().voxel, source.viewpoint, threads);
  samples.sensor = measured.sensor;
  return VerifyAlignment(target, samples, transform,
                         {target.noise().sigma_d * d, measured.noise_d * d}, {}, threads);
}

Matrix4 MovedAlongWorstDirection(const VerificationScore& score, const Matrix4& transform,
                                 double distance) {
  return MovedAlong(score, score.worst_direction, transform, distance);
}

Matrix4 MovedAlong(const VerificationScore& score, const Vector6& direction,
                   const Matrix4& transform, double distance) {
  const Vector6 step = distance * direction.normalized();
  const Vec3 omega = step.head<3>() / score.direction_lever;
  Matrix4 motion = Matrix4::Identity();
  if (omega.norm() > 0.0) {
    motion.topLeftCorner<3, 3>() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).matrix();
  }
  const Vec3& c = score.direction_centre;
  motion.topRightCorner<3, 1>() = c - motion.topLeftCorner<3, 3>() * c + step.tail<3>();
  return motion * transform;
}

bool PulledBySettling(VerificationScore& score, double displacement, double median_spacing,
                      const VerificationOptions& options) {
  if (!score.verified() ||
      !(displacement > SettleBound(score, options, options.min_band_spacings * median_spacing))) {
    return false;
  }
  score.verdict = Verdict::kPulled;
  score.settle_displacement = std::max(score.settle_displacement, displacement);
  return true;
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
