// Fast Global Registration (Zhou, Park, Koltun 2016): FPFH matches, the tuple test, then a
// fixed schedule of Geman-McClure line processes with a shrinking scale. Global: it ignores the
// initial transform, so it keeps its own loop (no convergence test) on the shared helpers.
#include <Eigen/Cholesky>
#include <cmath>
#include <random>

#include "method_runners.h"
#include "mlsreg/geometry/fpfh.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/surface_analysis.h"
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

// Random samples of a cloud with normals and FPFH features.
struct FeaturedSamples {
  std::vector<Vec3> points;
  std::vector<FpfhFeature> features;
};

// `stopped` is set when `should_stop` said stop (the samples are then unusable).
FeaturedSamples Describe(const PointCloud& cloud, const KdTree& tree, double normal_radius,
                         double feature_radius, int count, std::uint64_t seed,
                         const StopCheck& should_stop, bool& stopped) {
  FeaturedSamples out;
  const std::vector<std::uint32_t> indices =
      RandomSubsample(cloud.size(), static_cast<std::size_t>(count), seed);
  const SurfaceProperties surface =
      AnalyzeSurface(cloud.points, tree, normal_radius, cloud.viewpoint, indices, should_stop);
  if (surface.stopped) {
    stopped = true;
    return out;
  }
  std::vector<Vec3> normals;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    if (!surface.valid[k]) continue;
    out.points.push_back(cloud.points[indices[k]]);
    normals.push_back(surface.normals[k]);
  }
  const KdTree sample_tree(out.points);
  out.features = ComputeFpfh(out.points, normals, sample_tree, feature_radius, should_stop);
  stopped = out.features.size() != out.points.size();
  return out;
}

std::size_t NearestFeature(const FpfhFeature& f, const std::vector<FpfhFeature>& all) {
  std::size_t best = 0;
  float best_d2 = std::numeric_limits<float>::max();
  for (std::size_t j = 0; j < all.size(); ++j) {
    float d2 = 0.0f;
    for (int b = 0; b < 33; ++b) {
      const float diff = f[b] - all[j][b];
      d2 += diff * diff;
    }
    if (d2 < best_d2) {
      best_d2 = d2;
      best = j;
    }
  }
  return best;
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
  const KdTree source_tree(source.points);
  const double normal_radius = target.options().analysis_radius_d * d;
  bool stopped = false;
  const FeaturedSamples s = Describe(source, source_tree, normal_radius, p.feature_radius_d * d,
                                     p.samples, options.seed, callbacks.should_stop, stopped);
  const FeaturedSamples t =
      stopped ? FeaturedSamples{}
              : Describe(target.cloud(), target.tree(), normal_radius, p.feature_radius_d * d,
                         p.samples, options.seed + 1, callbacks.should_stop, stopped);
  result.num_samples = static_cast<int>(s.points.size());
  result.timings.preprocessing = Seconds(phase);

  // Matching: mutual nearest neighbours in feature space, then the tuple test.
  phase = Clock::now();
  std::vector<std::pair<std::size_t, std::size_t>> mutual;
  if (!stopped && !s.points.empty() && !t.points.empty()) {
    StopPoller stop(callbacks.should_stop, 16);  // each row is a pass over all features
    std::vector<std::size_t> t_to_s(t.points.size());
    for (std::size_t j = 0; j < t.points.size() && !stop.Poll(); ++j)
      t_to_s[j] = NearestFeature(t.features[j], s.features);
    for (std::size_t i = 0; i < s.points.size() && !stop.Poll(); ++i) {
      const std::size_t j = NearestFeature(s.features[i], t.features);
      if (t_to_s[j] == i) mutual.emplace_back(i, j);
    }
    stopped = stop.stopped();
  }
  if (stopped) {
    result.transform = Matrix4::Identity();
    result.termination = Termination::kCancelled;
    result.timings.total = Seconds(start);
    return result;
  }
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
        const double ls = (s.points[mutual[x].first] - s.points[mutual[y].first]).norm();
        const double lt = (t.points[mutual[x].second] - t.points[mutual[y].second]).norm();
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
  Vec3 cs = Vec3::Zero(), ct = Vec3::Zero();
  for (const Vec3& x : s.points) cs += x;
  for (const Vec3& x : t.points) ct += x;
  if (!s.points.empty()) cs /= static_cast<double>(s.points.size());
  if (!t.points.empty()) ct /= static_cast<double>(t.points.size());
  double scale = 0.0;
  for (const Vec3& x : s.points) scale = std::max(scale, (x - cs).norm());
  for (const Vec3& x : t.points) scale = std::max(scale, (x - ct).norm());
  if (!(scale > 0.0)) scale = 1.0;
  RigidTransform normalised = RigidTransform::Identity();  // maps normalised source to target
  auto to_world = [&](const RigidTransform& n) {
    RigidTransform w = RigidTransform::Identity();
    w.linear() = n.linear();
    w.translation() = ct + scale * n.translation() - n.linear() * cs;
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
      const Vec3 x = normalised * ((s.points[i] - cs) / scale);
      const Vec3 e = (t.points[j] - ct) / scale - x;
      const double r2 = e.squaredNorm();
      const double w = std::pow(mu / (mu + r2), 2);
      Eigen::Matrix<double, 3, 6> jacobian;  // de/d(omega, v) for x' = exp(omega) x + v
      jacobian << 0, -x.z(), x.y(), -1, 0, 0, x.z(), 0, -x.x(), 0, -1, 0, -x.y(), x.x(), 0, 0, 0,
          -1;
      h.noalias() += w * jacobian.transpose() * jacobian;
      g.noalias() += w * jacobian.transpose() * e;
      if (r2 < mu) {
        ++report.counts.matched;
        sum_squared += r2 * scale * scale;
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
