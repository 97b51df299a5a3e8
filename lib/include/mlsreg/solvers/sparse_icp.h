// SparseIcpSolver: the rigid update of Sparse ICP (Bouaziz, Tagliasacchi, Pauly 2013) for one ICP
// iteration with fixed correspondences: ADMM on sum_i |z_i|^p with z_i the residual.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {

enum class SicpMetric { kPointToPoint, kPointToPlane };

struct SparseIcpOptions {
  SicpMetric metric = SicpMetric::kPointToPlane;  // paper Table 2
  double p = 0.5;                                 // lp exponent (paper Table 2)
  double mu = 10.0;     // initial ADMM penalty, reset at every ICP iteration (reference impl.)
  double alpha = 1.2;   // penalty growth per outer iteration
  double max_mu = 1e5;  // penalty cap
  int max_outer = 10;   // ADMM iterations per ICP iteration (paper Table 2)
  int max_inner = 1;    // 1 = ADMM; > 1 alternates z and (R, t) before each multiplier update
  // Stop the ADMM when primal and dual residuals fall below this, in solver units (below).
  double stop = 1e-5;
  bool use_penalty = false;  // penalty method: no multiplier update
  // The reference implementation keeps the Lagrange multipliers from one ICP iteration to the
  // next although the correspondences (and so the constraints) change. That winds up on noisy
  // data (the pose keeps wandering); mlsreg resets them by default. true reproduces the reference.
  bool keep_multipliers = false;
  // Point-to-plane only: weight of the tangential damping term of PointToPlaneMotion. Set for
  // MLS correspondences (see RegistrationOptions::mls_tangential_weight); 0 elsewhere.
  double tangential_weight = 0.0;
  // Coordinates are divided by this length before the ADMM, which is therefore scale-free:
  // the shrinkage threshold of the lp prox depends on mu and on the length scale.
  double length_unit = 1.0;
};

// Validates ranges; the message names the offending field.
absl::Status ValidateSparseIcpOptions(const SparseIcpOptions& options);

// The lp proximal operator's scalar weight (reference implementation, 3 fixed-point steps):
// returns beta such that z = beta * h, with beta = 0 when |h| is below the threshold h_a(mu, p).
double LpShrinkWeight(double h_norm, double mu, double p);

// The same operator for one (mu, p), its threshold computed once: what the ADMM's inner loop
// applies to every residual (four pow calls per residual instead of eight; the same bits).
class LpShrink {
 public:
  LpShrink(double mu, double p);
  double operator()(double h_norm) const;

 private:
  double p_, p_over_mu_, ba_, ha_;
};

class SparseIcpSolver {
 public:
  explicit SparseIcpSolver(const SparseIcpOptions& options) : options_(options) {}
  void set_tangential_weight(double weight) { options_.tangential_weight = weight; }
  // A new length unit (and the stop threshold in the new units) for the following Steps.
  void set_length_unit(double unit, double stop) {
    options_.length_unit = unit;
    options_.stop = stop;
  }

  // Threads the point-to-plane ADMM's passes run on (the result is the same for any count).
  void set_threads(int threads) { threads_ = threads; }

  // Forget the Lagrange multipliers (a new registration with `samples` source samples).
  void Reset(std::size_t samples);

  // Runs the ADMM for one ICP iteration. `x` (current source samples) is moved in place; `q` and
  // `n` are the correspondences (n used by point-to-plane); samples with active[i] == 0 take no
  // part. Multipliers persist across calls, like the reference implementation. Returns the rigid
  // increment that was applied to x.
  RigidTransform Step(std::span<Vec3> x, std::span<const Vec3> q, std::span<const Vec3> n,
                      std::span<const std::uint8_t> active);

  // ADMM iterations run by the last Step.
  int last_outer_iterations() const { return last_outer_; }

 private:
  RigidTransform StepPointToPlane(std::span<const std::uint8_t> active);
  // The point-to-plane ADMM of one rigid step per iteration (max_inner = 1, the default) in one
  // pass over the samples per iteration (see sparse_icp.cc).
  RigidTransform RunPointToPlaneAdmmInOnePass(std::span<const std::uint8_t> active);
  RigidTransform StepPointToPoint(std::span<const std::uint8_t> active);
  template <typename Metric, typename RigidStep>
  RigidTransform RunAdmm(std::span<const std::uint8_t> active,
                         std::vector<typename Metric::Residual>& multiplier,
                         std::vector<typename Metric::Residual>& z,
                         std::vector<typename Metric::Residual>& shifted, RigidStep rigid_step);

  // One block's part of a pass of RunPointToPlaneAdmmInOnePass: the next step's sums, and the
  // largest motion (dual) and constraint residual (primal) of its samples.
  struct PassSums {
    PointToPlaneSums motion;
    double dual = 0.0, primal = 0.0;
  };
  struct CentroidSums {
    Vec3 sum = Vec3::Zero();
    std::size_t count = 0;
  };

  SparseIcpOptions options_;
  int threads_ = 1;
  int last_outer_ = 0;
  std::vector<PassSums> pass_partials_;  // per block of samples (ParallelSum)
  std::vector<CentroidSums> centroid_partials_;
  // Per-sample state and scratch (solver units); sized once per registration.
  std::vector<double> multiplier1_, z1_, u1_, weight_;
  std::vector<Vec3> multiplier3_, z3_, target3_, xs_, qs_, ns_, previous_;
};

}  // namespace mlsreg
