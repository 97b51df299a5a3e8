// Fast Global Registration (Zhou, Park, Koltun 2016): FPFH matches, the tuple test, then a
// fixed schedule of Geman-McClure line processes with a shrinking scale. Global: it ignores the
// initial transform, so it keeps its own loop (no convergence test) on the shared helpers.
#include <Eigen/Cholesky>
#include <cmath>
#include <optional>
#include <random>

#include "method_runners.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/registration/global_candidates.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using internal::Clock;
using internal::Seconds;

// FGR's constants (Zhou et al. 2016, reference implementation).
constexpr double kTupleScale = 0.95;
constexpr int kMaxTuples = 1000;
constexpr int kIterations = 64;
constexpr double kDivisionFactor = 1.4;
constexpr double kMaxCorrespondenceDistance = 0.025;  // in units of the normalisation scale

// The scale of the features FGR matches: voxel samples at a fifth of the FPFH radius (FGR's and
// Open3D's ratio), at most `samples` of them. The target's cached features are reused when they
// have this scale.
FeatureScale FgrScale(const FgrParams& p, double d) {
  FeatureScale scale;
  scale.feature_radius = p.feature_radius_d * d;
  scale.voxel = scale.feature_radius / kFeatureRadiusPerVoxel;
  scale.max_samples = static_cast<std::size_t>(p.samples);
  return scale;
}

bool SameScale(const FeatureScale& a, const FeatureScale& b) {
  return std::abs(a.voxel - b.voxel) <= 1e-9 * a.voxel &&
         std::abs(a.feature_radius - b.feature_radius) <= 1e-9 * a.feature_radius &&
         a.max_samples == b.max_samples;
}

}  // namespace

absl::StatusOr<RegistrationResult> internal::RunFastGlobalRegistration(
    const RegistrationProblem& problem) {
  const Target& target = *problem.target;
  const PointCloud& source = *problem.source;
  const RegistrationOptions& options = *problem.options;
  const RegistrationCallbacks& callbacks = *problem.callbacks;
  const Clock::time_point start = problem.start;
  RegistrationResult result;
  const double d = target.sampling_distance();
  result.sampling_distance = d;
  const FgrParams& p = options.fgr;

  // Preprocessing: features of both clouds.
  Clock::time_point phase = Clock::now();
  std::optional<KdTree> own_source_tree;
  if (!problem.source_tree) own_source_tree.emplace(source.points, problem.threads);
  const KdTree& source_tree = problem.source_tree ? *problem.source_tree : *own_source_tree;
  const double normal_radius = target.options().analysis_radius_d * d;
  const FeatureScale scale = FgrScale(p, d);
  const std::optional<FeatureCloud> s =
      BuildFeatureCloud(source.points, source_tree, nullptr, normal_radius, source.viewpoint, scale,
                        callbacks.should_stop);
  // The target's own features (made on first use) serve when they are at FGR's scale.
  std::optional<FeatureCloud> own_target;
  const bool target_scale = SameScale(FeatureScaleFor(target.points(), target.scales()), scale);
  const FeatureCloud* t = s && target_scale ? target.features(callbacks.should_stop) : nullptr;
  if (s && !target_scale) {
    own_target = BuildFeatureCloud(target.points(), target.tree(), &target.surface(), 0.0,
                                   target.cloud().viewpoint, scale, callbacks.should_stop);
    t = own_target ? &*own_target : nullptr;
  }
  bool stopped = !s || !t;
  result.num_samples = s ? static_cast<int>(s->size()) : 0;
  result.timings.preprocessing = Seconds(phase);

  // Matching: mutual nearest neighbours in feature space, then the tuple test.
  phase = Clock::now();
  FeatureMatches matched;
  if (!stopped) {
    matched = MatchFeatures(*s, *t, /*min_mutual=*/0, callbacks.should_stop);
    stopped = matched.stopped;
  }
  if (stopped) {
    result.transform = Matrix4::Identity();
    result.termination = Termination::kCancelled;
    result.timings.total = Seconds(start);
    return result;
  }
  const auto& mutual = matched.pairs;
  std::vector<std::pair<std::size_t, std::size_t>> corr;
  std::mt19937_64 rng(options.seed);
  if (mutual.size() >= 3) {
    std::uniform_int_distribution<std::size_t> pick(0, mutual.size() - 1);
    const std::size_t trials = 100 * mutual.size();
    int tuples = 0;
    for (std::size_t trial = 0; trial < trials && tuples < kMaxTuples; ++trial) {
      const std::size_t a = pick(rng), b = pick(rng), c = pick(rng);
      if (a == b || b == c || a == c) continue;
      bool consistent = true;
      for (auto [x, y] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) {
        const double ls = (s->points[mutual[x].first] - s->points[mutual[y].first]).norm();
        const double lt = (t->points[mutual[x].second] - t->points[mutual[y].second]).norm();
        if (!(ls > 0.0 && lt > 0.0) || ls / lt < kTupleScale || lt / ls < kTupleScale) {
          consistent = false;
          break;
        }
      }
      if (!consistent) continue;
      corr.push_back(mutual[a]);
      corr.push_back(mutual[b]);
      corr.push_back(mutual[c]);
      ++tuples;
    }
  }
  result.timings.matching = Seconds(phase);

  // Optimisation in normalised coordinates (each cloud centred, both scaled by one factor).
  phase = Clock::now();
  const Vec3 cs = Centroid(s->points), ct = Centroid(t->points);
  double extent = 0.0;
  for (const Vec3& x : s->points) extent = std::max(extent, (x - cs).norm());
  for (const Vec3& x : t->points) extent = std::max(extent, (x - ct).norm());
  if (!(extent > 0.0)) extent = 1.0;
  RigidTransform normalised = RigidTransform::Identity();  // maps normalised source to target
  auto to_world = [&](const RigidTransform& n) {
    RigidTransform w = RigidTransform::Identity();
    w.linear() = n.linear();
    w.translation() = ct + extent * n.translation() - n.linear() * cs;
    return w;
  };
  double mu = 1.0;  // squared distance scale of the Geman-McClure weight
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  result.termination = corr.size() >= static_cast<std::size_t>(options.min_correspondences)
                           ? Termination::kConverged
                           : Termination::kTooFewCorrespondences;
  for (int iteration = 1; corr.size() >= static_cast<std::size_t>(options.min_correspondences) &&
                          iteration <= kIterations;
       ++iteration) {
    if (callbacks.should_stop && callbacks.should_stop()) {
      result.termination = Termination::kCancelled;
      break;
    }
    if (iteration > 1 && (iteration - 1) % 4 == 0 &&
        mu > kMaxCorrespondenceDistance * kMaxCorrespondenceDistance) {
      mu /= kDivisionFactor;
    }
    Matrix6 h = Matrix6::Zero();
    Vector6 g = Vector6::Zero();
    IterationReport report;
    report.iteration = iteration;
    double sum_squared = 0.0;
    for (const auto& [i, j] : corr) {
      const Vec3 x = normalised * ((s->points[i] - cs) / extent);
      const Vec3 e = (t->points[j] - ct) / extent - x;
      const double r2 = e.squaredNorm();
      const double w = std::pow(mu / (mu + r2), 2);
      Eigen::Matrix<double, 3, 6> jacobian;  // de/d(omega, v) for x' = exp(omega) x + v
      jacobian << 0, -x.z(), x.y(), -1, 0, 0, x.z(), 0, -x.x(), 0, -1, 0, -x.y(), x.x(), 0, 0, 0,
          -1;
      h.noalias() += w * jacobian.transpose() * jacobian;
      g.noalias() += w * jacobian.transpose() * e;
      if (r2 < mu) {
        ++report.counts.matched;
        sum_squared += r2 * extent * extent;
      } else {
        ++report.counts.rejected_distance;
      }
    }
    const Vector6 delta = SolveConstrainedStep(h, -g);
    if (delta.allFinite()) normalised = TwistIncrement(delta) * normalised;
    internal::SetRmse(report, sum_squared, d);
    result.iterations = iteration;
    internal::RecordIteration(result, report, to_world(normalised), callbacks, start);
  }
  result.converged = result.termination == Termination::kConverged;
  result.transform = to_world(normalised).matrix();
  result.timings.optimisation = Seconds(phase);
  result.timings.total = Seconds(start);
  return result;
}

}  // namespace mlsreg
