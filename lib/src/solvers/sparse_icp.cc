#include "mlsreg/solvers/sparse_icp.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "mlsreg/core/parallel_sum.h"

namespace mlsreg {

absl::Status ValidateSparseIcpOptions(const SparseIcpOptions& o) {
  auto bad = [](const char* field, const char* rule) {
    return absl::InvalidArgumentError(absl::StrCat("sicp.", field, " ", rule));
  };
  if (!(o.p > 0.0 && o.p <= 1.0)) return bad("p", "must be in (0, 1]");
  if (!(o.mu > 0.0 && std::isfinite(o.mu))) return bad("mu", "must be positive");
  if (!(o.alpha >= 1.0 && std::isfinite(o.alpha))) return bad("alpha", "must be >= 1");
  if (!(o.max_mu >= o.mu && std::isfinite(o.max_mu))) return bad("max_mu", "must be >= mu");
  if (o.max_outer < 1 || o.max_outer > 10000) return bad("max_outer", "must be in [1, 10000]");
  if (o.max_inner < 1 || o.max_inner > 1000) return bad("max_inner", "must be in [1, 1000]");
  if (!(o.stop >= 0.0 && std::isfinite(o.stop))) return bad("stop", "must be >= 0");
  if (!(o.length_unit > 0.0 && std::isfinite(o.length_unit))) {
    return bad("length_unit", "must be positive");
  }
  return absl::OkStatus();
}

LpShrink::LpShrink(double mu, double p)
    : p_(p),
      p_over_mu_(p / mu),
      ba_(std::pow((2.0 / mu) * (1.0 - p), 1.0 / (2.0 - p))),
      ha_(ba_ + p_over_mu_ * std::pow(ba_, p - 1.0)) {}

double LpShrink::operator()(double h_norm) const {
  if (h_norm <= ha_) return 0.0;
  double beta = (ba_ / h_norm + 1.0) / 2.0;
  const double scale = p_over_mu_ * std::pow(h_norm, p_ - 2.0);
  for (int k = 0; k < 3; ++k) beta = 1.0 - scale * std::pow(beta, p_ - 1.0);
  return beta;
}

double LpShrinkWeight(double h_norm, double mu, double p) { return LpShrink(mu, p)(h_norm); }

void SparseIcpSolver::Reset(std::size_t samples) {
  multiplier1_.assign(samples, 0.0);
  multiplier3_.assign(samples, Vec3::Zero());
  z1_.assign(samples, 0.0);
  u1_.assign(samples, 0.0);
  weight_.assign(samples, 0.0);
  z3_.assign(samples, Vec3::Zero());
  target3_.assign(samples, Vec3::Zero());
  xs_.assign(samples, Vec3::Zero());
  qs_.assign(samples, Vec3::Zero());
  ns_.assign(samples, Vec3::Zero());
  previous_.assign(samples, Vec3::Zero());
}

RigidTransform SparseIcpSolver::Step(std::span<Vec3> x, std::span<const Vec3> q,
                                     std::span<const Vec3> n,
                                     std::span<const std::uint8_t> active) {
  if (xs_.size() != x.size()) Reset(x.size());
  if (!options_.keep_multipliers) {
    std::fill(multiplier1_.begin(), multiplier1_.end(), 0.0);
    std::fill(multiplier3_.begin(), multiplier3_.end(), Vec3::Zero());
  }
  // Work in solver units: positions divided by the length unit, relative to a common origin
  // (the centroid of the active correspondences) for conditioning.
  const double inv_unit = 1.0 / options_.length_unit;
  Vec3 origin = Vec3::Zero();
  std::size_t count = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!active[i]) continue;
    origin += q[i];
    ++count;
  }
  if (count == 0) return RigidTransform::Identity();
  origin /= static_cast<double>(count);
  for (std::size_t i = 0; i < x.size(); ++i) {
    xs_[i] = (x[i] - origin) * inv_unit;
    qs_[i] = (q[i] - origin) * inv_unit;
    ns_[i] = n[i];
    weight_[i] = active[i] ? 1.0 : 0.0;
  }

  const RigidTransform scaled = options_.metric == SicpMetric::kPointToPlane
                                    ? StepPointToPlane(active)
                                    : StepPointToPoint(active);

  // Back to input units: x' = origin + L * (R (x - origin) / L + t).
  RigidTransform increment = RigidTransform::Identity();
  increment.linear() = scaled.linear();
  increment.translation() =
      origin + options_.length_unit * scaled.translation() - scaled.linear() * origin;
  for (Vec3& p : x) p = increment * p;
  return increment;
}

namespace {

// The two Sparse ICP metrics differ only in the residual (scalar distance to the tangent plane,
// or 3-vector to the point) and in the rigid step that fits the shifted targets.
struct PointToPlaneMetric {
  using Residual = double;
  static double Of(const Vec3& x, const Vec3& q, const Vec3& n) { return n.dot(x - q); }
  static double Norm(double r) { return std::abs(r); }
};

struct PointToPointMetric {
  using Residual = Vec3;
  static Vec3 Of(const Vec3& x, const Vec3& q, const Vec3&) { return x - q; }
  static double Norm(const Vec3& r) { return r.norm(); }
};

}  // namespace

// One ICP iteration of ADMM (reference: OpenGP sparseicp ICP.h, SICP::point_to_*):
//   z = prox_{|.|^p / mu}(r(x) + c / mu)      (shrinkage)
//   (R, t) = argmin sum |r(R x + t) - (z - c / mu)|^2
//   c += mu (r(x) - z);  mu *= alpha
template <typename Metric, typename RigidStep>
RigidTransform SparseIcpSolver::RunAdmm(std::span<const std::uint8_t> active,
                                        std::vector<typename Metric::Residual>& multiplier,
                                        std::vector<typename Metric::Residual>& z,
                                        std::vector<typename Metric::Residual>& shifted,
                                        RigidStep rigid_step) {
  const std::size_t m = xs_.size();
  RigidTransform total = RigidTransform::Identity();
  double mu = options_.mu;
  last_outer_ = 0;
  for (int outer = 0; outer < options_.max_outer; ++outer) {
    ++last_outer_;
    double dual = 0.0;
    const LpShrink shrink(mu, options_.p);
    for (int inner = 0; inner < options_.max_inner; ++inner) {
      for (std::size_t i = 0; i < m; ++i) {
        if (!active[i]) continue;
        // Concrete type, not auto: an Eigen expression would outlive its temporaries.
        const typename Metric::Residual h = Metric::Of(xs_[i], qs_[i], ns_[i]) + multiplier[i] / mu;
        z[i] = shrink(Metric::Norm(h)) * h;
        shifted[i] = z[i] - multiplier[i] / mu;
      }
      std::copy(xs_.begin(), xs_.end(), previous_.begin());
      const RigidTransform step = rigid_step();
      dual = 0.0;
      for (std::size_t i = 0; i < m; ++i) {
        xs_[i] = step * xs_[i];
        if (active[i]) dual = std::max(dual, (xs_[i] - previous_[i]).norm());
      }
      total = step * total;
      if (dual < options_.stop) break;
    }
    double primal = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      if (!active[i]) continue;
      const typename Metric::Residual residual = Metric::Of(xs_[i], qs_[i], ns_[i]) - z[i];
      if (!options_.use_penalty) multiplier[i] += mu * residual;
      primal = std::max(primal, Metric::Norm(residual));
    }
    if (mu < options_.max_mu) mu *= options_.alpha;
    if (primal < options_.stop && dual < options_.stop) break;
  }
  return total;
}

// A pass of the ADMM below costs about 30 ns a sample: below this many per thread, waking a
// thread for it costs more than it saves (BM_MlsSicpThreads, 2026-12-07: every pass on two
// threads made it slower).
constexpr std::size_t kMinSamplesPerThread = 4096;

// With one rigid step per iteration, what the iteration does to a sample (move it by the last
// step, update its multiplier, shrink its residual for the next step, add its terms to the next
// step's normal equations) needs that sample alone and the step, so it is one pass over the
// samples, on the threads, summed in fixed blocks (ParallelSum: the same for any thread count).
// The steps linearise the rotation about the samples' centroid, which each step moves rigidly
// with them. The same iteration as RunAdmm, up to the rounding of the sums.
RigidTransform SparseIcpSolver::RunPointToPlaneAdmmInOnePass(std::span<const std::uint8_t> active) {
  const std::size_t m = xs_.size();
  const double lambda = options_.tangential_weight;
  const auto merge = [](PassSums& total, const PassSums& block) {
    total.motion.Merge(block.motion);
    total.dual = std::max(total.dual, block.dual);
    total.primal = std::max(total.primal, block.primal);
  };
  // The active samples' centroid (their weights are 1).
  const CentroidSums sum = ParallelSum(
      m, threads_, centroid_partials_,
      [&](std::size_t i, CentroidSums& block) {
        if (!active[i]) return;
        block.sum += xs_[i];
        ++block.count;
      },
      [](CentroidSums& total, const CentroidSums& block) {
        total.sum += block.sum;
        total.count += block.count;
      },
      kMinSamplesPerThread);
  if (sum.count == 0) return RigidTransform::Identity();
  Vec3 centre = sum.sum / static_cast<double>(sum.count);

  // One pass: `step` (null: none) moves every sample; with update_mu > 0 the active ones'
  // multipliers take the constraint residual (the iteration that made `step` ends); then their
  // residuals are shrunk at `mu` (`shrink`) into the next step's targets and sums about `centre`.
  const auto pass = [&](const RigidTransform* step, double update_mu, const LpShrink& shrink,
                        double mu) {
    return ParallelSum(
        m, threads_, pass_partials_,
        [&](std::size_t i, PassSums& block) {
          if (step != nullptr) {
            const Vec3 moved = *step * xs_[i];
            if (active[i]) block.dual = std::max(block.dual, (moved - xs_[i]).norm());
            xs_[i] = moved;
          }
          if (!active[i]) return;
          const double r = PointToPlaneMetric::Of(xs_[i], qs_[i], ns_[i]);
          if (update_mu > 0.0) {
            const double residual = r - z1_[i];
            if (!options_.use_penalty) multiplier1_[i] += update_mu * residual;
            block.primal = std::max(block.primal, std::abs(residual));
          }
          const double h = r + multiplier1_[i] / mu;
          z1_[i] = shrink(std::abs(h)) * h;
          u1_[i] = z1_[i] - multiplier1_[i] / mu;
          block.motion.Add(xs_[i] - centre, xs_[i] - qs_[i], ns_[i], u1_[i], 1.0, lambda);
        },
        merge, kMinSamplesPerThread);
  };

  double mu = options_.mu;
  PassSums sums = pass(nullptr, 0.0, LpShrink(mu, options_.p), mu);
  RigidTransform total = RigidTransform::Identity();
  last_outer_ = 0;
  for (int outer = 0; outer < options_.max_outer; ++outer) {
    ++last_outer_;
    const RigidTransform step = sums.motion.Solve(centre);
    total = step * total;
    centre = step * centre;
    const double next_mu = mu < options_.max_mu ? mu * options_.alpha : mu;
    sums = pass(&step, mu, LpShrink(next_mu, options_.p), next_mu);
    mu = next_mu;
    if (sums.primal < options_.stop && sums.dual < options_.stop) break;
  }
  return total;
}

RigidTransform SparseIcpSolver::StepPointToPlane(std::span<const std::uint8_t> active) {
  if (options_.max_inner == 1) return RunPointToPlaneAdmmInOnePass(active);
  // Fit n . (R x + t - q) = z - c / mu.
  return RunAdmm<PointToPlaneMetric>(active, multiplier1_, z1_, u1_, [&] {
    return PointToPlaneMotion(xs_, qs_, ns_, u1_, weight_, options_.tangential_weight);
  });
}

RigidTransform SparseIcpSolver::StepPointToPoint(std::span<const std::uint8_t> active) {
  // Fit R x + t = q + z - c / mu.
  return RunAdmm<PointToPointMetric>(active, multiplier3_, z3_, target3_, [&] {
    for (std::size_t i = 0; i < xs_.size(); ++i) target3_[i] += qs_[i];
    const RigidTransform step = PointToPointMotion(xs_, target3_, weight_);
    for (std::size_t i = 0; i < xs_.size(); ++i) target3_[i] -= qs_[i];
    return step;
  });
}

}  // namespace mlsreg
