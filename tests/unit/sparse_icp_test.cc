#include "mlsreg/solvers/sparse_icp.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "mlsreg/core/transform.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

RigidTransform KnownMotion() {
  RigidTransform t = RigidTransform::Identity();
  t.linear() = ExpSo3(Vec3(0.2, -0.1, 0.3));
  t.translation() = Vec3(0.5, -0.2, 0.1);
  return t;
}

std::vector<Vec3> RandomPoints(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> p(n);
  for (Vec3& v : p) v = Vec3(u(rng), u(rng), u(rng));
  return p;
}

TEST(LpShrinkTest, ZeroBelowThresholdAndApproachesIdentityFarAway) {
  const double mu = 10.0, p = 0.5;
  const double ba = std::pow((2.0 / mu) * (1.0 - p), 1.0 / (2.0 - p));
  const double ha = ba + (p / mu) * std::pow(ba, p - 1.0);
  EXPECT_EQ(LpShrinkWeight(0.99 * ha, mu, p), 0.0);
  const double beta = LpShrinkWeight(1.01 * ha, mu, p);
  EXPECT_GT(beta, 0.0);
  EXPECT_LT(beta, 1.0);
  EXPECT_GT(LpShrinkWeight(1000.0, mu, p), 0.999);
  // p = 1 is soft thresholding: z = h - sign(h) / mu.
  EXPECT_NEAR(LpShrinkWeight(2.0, mu, 1.0) * 2.0, 2.0 - 1.0 / mu, 1e-12);
  // The prox minimises |z|^p + mu/2 (z - h)^2: check against a dense 1-D search.
  for (double h : {0.4, 0.7, 1.5, 3.0}) {
    auto objective = [&](double z) {
      return std::pow(std::abs(z), p) + 0.5 * mu * (z - h) * (z - h);
    };
    double best_z = 0, best = objective(0);
    for (double z = 0; z <= h; z += 1e-5) {
      if (objective(z) < best) best = objective(z), best_z = z;
    }
    EXPECT_NEAR(LpShrinkWeight(h, mu, p) * h, best_z, 1e-3) << "h = " << h;
  }
}

TEST(RigidMotionTest, PointToPointRecoversExactTransform) {
  const std::vector<Vec3> x = RandomPoints(50, 1);
  const RigidTransform truth = KnownMotion();
  std::vector<Vec3> y;
  for (const Vec3& p : x) y.push_back(truth * p);
  const std::vector<double> w(x.size(), 1.0);
  const RigidTransform estimate = PointToPointMotion(x, y, w);
  EXPECT_TRUE(estimate.matrix().isApprox(truth.matrix(), 1e-12));
}

TEST(RigidMotionTest, PointToPointIgnoresZeroWeights) {
  std::vector<Vec3> x = RandomPoints(50, 2);
  const RigidTransform truth = KnownMotion();
  std::vector<Vec3> y;
  for (const Vec3& p : x) y.push_back(truth * p);
  std::vector<double> w(x.size(), 1.0);
  for (int i = 0; i < 10; ++i) {
    y[i] += Vec3(5, 5, 5);  // gross outliers, weight 0
    w[i] = 0.0;
  }
  EXPECT_TRUE(PointToPointMotion(x, y, w).matrix().isApprox(truth.matrix(), 1e-12));
}

TEST(RigidMotionTest, PointToPlaneConvergesToExactTransform) {
  // Correspondences with their true normals: iterating the linearised step converges to truth.
  const std::vector<Vec3> x0 = RandomPoints(200, 3);
  RigidTransform truth = RigidTransform::Identity();
  truth.linear() = ExpSo3(Vec3(0.05, -0.03, 0.04));
  truth.translation() = Vec3(0.05, 0.02, -0.03);
  std::vector<Vec3> y, n;
  std::mt19937_64 rng(4);
  std::normal_distribution<double> g;
  for (const Vec3& p : x0) {
    y.push_back(truth * p);
    n.push_back(Vec3(g(rng), g(rng), g(rng)).normalized());
  }
  const std::vector<double> u(x0.size(), 0.0), w(x0.size(), 1.0);
  std::vector<Vec3> x = x0;
  RigidTransform total = RigidTransform::Identity();
  for (int it = 0; it < 10; ++it) {
    const RigidTransform step = PointToPlaneMotion(x, y, n, u, w);
    for (Vec3& p : x) p = step * p;
    total = step * total;
  }
  EXPECT_TRUE(total.matrix().isApprox(truth.matrix(), 1e-10));
  EXPECT_NEAR(total.linear().determinant(), 1.0, 1e-12);
}

TEST(RigidMotionTest, TangentialDampingPinsSlidingAndKeepsTheNormalFit) {
  // Points 0.5 above the plane z = 0 and 0.1 off their foot points along x. The planes alone
  // leave x/y sliding and the rotation about z free; the damping term fixes them: the step is
  // exactly the translation (-0.1, 0, -0.5) that zeroes both residuals.
  std::vector<Vec3> x, y, n;
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    y.emplace_back(coordinate(rng), coordinate(rng), 0.0);
    x.push_back(y.back() + Vec3(0.1, 0.0, 0.5));
    n.emplace_back(0.0, 0.0, 1.0);
  }
  const std::vector<double> u(x.size(), 0.0), w(x.size(), 1.0);
  const RigidTransform step = PointToPlaneMotion(x, y, n, u, w, /*tangential_weight=*/1.0);
  EXPECT_TRUE(step.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_TRUE(step.translation().isApprox(Vec3(-0.1, 0.0, -0.5), 1e-12));
}

// The step from its definition: the normal equations of sum w (n.(x' - y) - u)^2 + lambda w
// |P (x' - y)|^2, P = I - n n^T, built from each correspondence's projected Jacobian.
RigidTransform ReferencePointToPlaneStep(const std::vector<Vec3>& x, const std::vector<Vec3>& y,
                                         const std::vector<Vec3>& n, const std::vector<double>& u,
                                         const std::vector<double>& w, double lambda) {
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  Vec3 mean = Vec3::Zero();
  double total = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mean += w[i] * x[i];
    total += w[i];
  }
  mean /= total;
  Matrix6 h = Matrix6::Zero();
  Vector6 g = Vector6::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Vec3 xc = x[i] - mean;
    Eigen::Matrix<double, 3, 6> jacobian;  // d(R x + t)/d(omega, t) at the identity
    jacobian.leftCols<3>() << 0.0, xc.z(), -xc.y(), -xc.z(), 0.0, xc.x(), xc.y(), -xc.x(), 0.0;
    jacobian.rightCols<3>().setIdentity();
    const Eigen::Matrix<double, 1, 6> row = n[i].transpose() * jacobian;
    const Eigen::Matrix3d tangent = Eigen::Matrix3d::Identity() - n[i] * n[i].transpose();
    const Eigen::Matrix<double, 3, 6> projected = tangent * jacobian;
    h += w[i] * row.transpose() * row + lambda * w[i] * projected.transpose() * projected;
    g -= w[i] * ((x[i] - y[i]).dot(n[i]) - u[i]) * row.transpose() +
         lambda * w[i] * projected.transpose() * (tangent * (x[i] - y[i]));
  }
  const Vector6 step = SolveConstrainedStep(h, g);
  RigidTransform out = RigidTransform::Identity();
  out.linear() = ExpSo3(step.head<3>());
  out.translation() = mean + step.tail<3>() - out.linear() * mean;
  return out;
}

TEST(RigidMotionTest, TheTangentialTermIsTheStepOfItsDefinition) {
  // PointToPlaneMotion sums the tangential term through the moments of the points; the step must
  // be the one its definition gives, for any damping weight and uneven weights.
  const std::vector<Vec3> x = RandomPoints(300, 21), jitter = RandomPoints(300, 22);
  std::vector<Vec3> y, n;
  std::vector<double> u, w;
  std::mt19937_64 rng(23);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> weight(0.0, 2.0);
  for (std::size_t i = 0; i < x.size(); ++i) {
    y.push_back(KnownMotion() * x[i] + 0.05 * jitter[i]);
    n.push_back(Vec3(g(rng), g(rng), g(rng)).normalized());
    u.push_back(0.01 * g(rng));
    w.push_back(i % 7 == 0 ? 0.0 : weight(rng));
  }
  for (double lambda : {0.0, 0.3, 1.0, 2.5}) {
    SCOPED_TRACE(lambda);
    const RigidTransform step = PointToPlaneMotion(x, y, n, u, w, lambda);
    const RigidTransform reference = ReferencePointToPlaneStep(x, y, n, u, w, lambda);
    EXPECT_LT((step.matrix() - reference.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(RigidMotionTest, CorrespondencesOnOnePlaneMoveOnlyAlongTheNormal) {
  // Every partner on the plane z = 0 with normal z, points tilted slightly and 0.5 above: the
  // planes constrain the z translation and the tilts about x and y, nothing else. The step must
  // level and lower the points without sliding them (a plain LDLT solve of the rank-3 system
  // returned in-plane translations of ~1e10 on real data).
  std::vector<Vec3> x, y, n;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  // The whole scene is turned off the axes, so the free directions carry round-off (~1e-16)
  // instead of exact zeros, as on real data.
  const Eigen::Matrix3d tilt = ExpSo3(Vec3(0.01, -0.02, 0.0));
  const Eigen::Matrix3d turn = ExpSo3(Vec3(0.7, -0.4, 1.1));
  for (int i = 0; i < 100; ++i) {
    const Vec3 on_plane(coordinate(rng), coordinate(rng), 0.0);
    y.push_back(turn * on_plane);
    x.push_back(turn * (tilt * on_plane + Vec3(0.0, 0.0, 0.5)));
    n.push_back(turn * Vec3::UnitZ());
  }
  const std::vector<double> u(x.size(), 0.0), w(x.size(), 1.0);
  const RigidTransform step = PointToPlaneMotion(x, y, n, u, w);
  ASSERT_TRUE(step.matrix().allFinite());
  double worst_height = 0.0, worst_slide = 0.0;
  for (const Vec3& p : x) {
    const Vec3 moved = turn.transpose() * (step * p), before = turn.transpose() * p;
    worst_height = std::max(worst_height, std::abs(moved.z()));
    // In-plane motion is only what leveling the tilt implies (second order in 0.02).
    worst_slide = std::max(worst_slide, (moved - before).head<2>().norm());
  }
  EXPECT_LT(worst_height, 1e-3);
  EXPECT_LT(worst_slide, 0.02);
}

TEST(RigidMotionTest, ConstrainedStepIgnoresUnconstrainedDirections) {
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  Matrix6 h = Matrix6::Zero();
  h.diagonal() << 2.0, 4.0, 1e-17, 0.0, 0.0, 8.0;
  Vector6 rhs;
  rhs << 2.0, 4.0, 1.0, 1.0, 1.0, 8.0;
  Vector6 expected;
  expected << 1.0, 1.0, 0.0, 0.0, 0.0, 1.0;
  EXPECT_TRUE(SolveConstrainedStep(h, rhs).isApprox(expected, 1e-12));
  EXPECT_TRUE(SolveConstrainedStep(Matrix6::Zero(), rhs).isZero());
  h(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(SolveConstrainedStep(h, rhs).isZero());
}

TEST(RigidMotionTest, TangentialDampingLeavesExactFootPointFitsAlone) {
  // Foot-point correspondences (x - y along n): the damped step still converges to the truth.
  const std::vector<Vec3> x0 = RandomPoints(200, 9);
  RigidTransform truth = RigidTransform::Identity();
  truth.linear() = ExpSo3(Vec3(0.03, 0.02, -0.04));
  truth.translation() = Vec3(-0.02, 0.04, 0.01);
  std::vector<Vec3> y, n;
  std::mt19937_64 rng(10);
  std::normal_distribution<double> g;
  for (const Vec3& p : x0) {
    y.push_back(truth * p);
    n.push_back(Vec3(g(rng), g(rng), g(rng)).normalized());
  }
  const std::vector<double> u(x0.size(), 0.0), w(x0.size(), 1.0);
  std::vector<Vec3> x = x0;
  RigidTransform total = RigidTransform::Identity();
  for (int it = 0; it < 20; ++it) {
    const RigidTransform step = PointToPlaneMotion(x, y, n, u, w, 1.0);
    for (Vec3& p : x) p = step * p;
    total = step * total;
  }
  EXPECT_TRUE(total.matrix().isApprox(truth.matrix(), 1e-9));
}

TEST(SparseIcpSolverTest, RobustToGrossOutliers) {
  // Fixed correspondences, 30 % of them gross outliers: the lp (p = 0.5) ADMM still recovers the
  // transform that least squares would miss.
  const std::vector<Vec3> x0 = RandomPoints(300, 5);
  RigidTransform truth = RigidTransform::Identity();
  truth.linear() = ExpSo3(Vec3(0.02, 0.01, -0.02));
  truth.translation() = Vec3(0.01, -0.02, 0.015);
  std::vector<Vec3> q;
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(-1, 1);
  for (std::size_t i = 0; i < x0.size(); ++i) {
    q.push_back(truth * x0[i]);
    if (i % 10 < 3) q.back() += Vec3(u(rng), u(rng), u(rng));
  }
  const std::vector<Vec3> n(x0.size(), Vec3::UnitZ());
  const std::vector<std::uint8_t> active(x0.size(), 1);
  SparseIcpOptions options;
  options.metric = SicpMetric::kPointToPoint;
  options.max_outer = 200;
  options.length_unit = 0.1;
  options.stop = 1e-9;
  SparseIcpSolver solver(options);
  std::vector<Vec3> x = x0;
  RigidTransform total = RigidTransform::Identity();
  for (int it = 0; it < 5; ++it) total = solver.Step(x, q, n, active) * total;
  const double rotation_error =
      Eigen::AngleAxisd(truth.linear().transpose() * total.linear()).angle();
  EXPECT_LT(rotation_error, 1e-3);
  EXPECT_LT((total.translation() - truth.translation()).norm(), 1e-3);
  // Least squares (Procrustes on all pairs) is visibly biased by the outliers.
  const std::vector<double> w(x0.size(), 1.0);
  const RigidTransform ls = PointToPointMotion(x0, q, w);
  EXPECT_GT((ls.translation() - truth.translation()).norm(), 3e-3);
}

// The point-to-plane ADMM as the reference implementation iterates it (one rigid step per
// iteration, the centroid recomputed at each step, every sum in sample order), in the solver's
// frame (the active targets' centroid as origin, length unit 1): the increment applied to x.
RigidTransform ReferencePointToPlaneAdmm(std::vector<Vec3> x, std::vector<Vec3> q,
                                         const std::vector<Vec3>& n,
                                         const std::vector<std::uint8_t>& active,
                                         const SparseIcpOptions& o) {
  Vec3 origin = Vec3::Zero();
  int count = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!active[i]) continue;
    origin += q[i];
    ++count;
  }
  origin /= count;
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] -= origin;
    q[i] -= origin;
  }
  std::vector<double> c(x.size(), 0.0), z(x.size(), 0.0), u(x.size(), 0.0), w(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) w[i] = active[i] ? 1.0 : 0.0;
  double mu = o.mu;
  RigidTransform total = RigidTransform::Identity();
  for (int outer = 0; outer < o.max_outer; ++outer) {
    const LpShrink shrink(mu, o.p);
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!active[i]) continue;
      const double h = n[i].dot(x[i] - q[i]) + c[i] / mu;
      z[i] = shrink(std::abs(h)) * h;
      u[i] = z[i] - c[i] / mu;
    }
    const RigidTransform step = PointToPlaneMotion(x, q, n, u, w, o.tangential_weight);
    double dual = 0.0, primal = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const Vec3 moved = step * x[i];
      if (active[i]) dual = std::max(dual, (moved - x[i]).norm());
      x[i] = moved;
    }
    total = step * total;
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!active[i]) continue;
      const double residual = n[i].dot(x[i] - q[i]) - z[i];
      c[i] += mu * residual;
      primal = std::max(primal, std::abs(residual));
    }
    if (mu < o.max_mu) mu *= o.alpha;
    if (primal < o.stop && dual < o.stop) break;
  }
  RigidTransform increment = total;
  increment.translation() = origin + total.translation() - total.linear() * origin;
  return increment;
}

// The solver runs each point-to-plane ADMM iteration as one pass over the samples, on threads,
// its sums in fixed blocks: the reference's iteration up to rounding, the same bits for any
// thread count. Correspondences with 30 % gross outliers, some samples inactive, damping on.
TEST(SparseIcpSolverTest, OnePassPointToPlaneAdmmIsTheReferenceIterationOnAnyThreads) {
  const std::vector<Vec3> x0 = RandomPoints(10000, 7);  // enough for the passes to split
  RigidTransform truth = RigidTransform::Identity();
  truth.linear() = ExpSo3(Vec3(0.01, -0.02, 0.015));
  truth.translation() = Vec3(0.02, 0.01, -0.01);
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> uniform(-1, 1);
  std::vector<Vec3> q, n;
  std::vector<std::uint8_t> active;
  for (std::size_t i = 0; i < x0.size(); ++i) {
    n.push_back(Vec3(uniform(rng), uniform(rng), uniform(rng)).normalized());
    q.push_back(truth * x0[i] + 0.3 * Vec3(uniform(rng), uniform(rng), uniform(rng)).cross(n[i]));
    if (i % 10 < 3) q.back() += 0.5 * uniform(rng) * n[i];
    active.push_back(i % 17 != 0);
  }
  SparseIcpOptions options;  // point-to-plane, p = 0.5, 10 iterations of one step each
  options.tangential_weight = 0.1;
  const RigidTransform reference = ReferencePointToPlaneAdmm(x0, q, n, active, options);
  std::vector<RigidTransform> steps;
  for (int threads : {1, 2, 3}) {
    SparseIcpSolver solver(options);
    solver.set_threads(threads);
    std::vector<Vec3> x = x0;
    steps.push_back(solver.Step(x, q, n, active));
    EXPECT_EQ(solver.last_outer_iterations(), options.max_outer);
    EXPECT_TRUE(x[5].isApprox(steps.back() * x0[5], 1e-12));  // x moved by the increment
  }
  EXPECT_TRUE(steps[0].matrix().isApprox(reference.matrix(), 1e-9)) << steps[0].matrix() << "\n"
                                                                    << reference.matrix();
  EXPECT_GT((reference.matrix() - Matrix4::Identity()).norm(), 1e-3);  // it moved
  EXPECT_EQ(steps[1].matrix(), steps[0].matrix());
  EXPECT_EQ(steps[2].matrix(), steps[0].matrix());
}

TEST(SparseIcpOptionsTest, RejectsOutOfRangeNamingTheField) {
  SparseIcpOptions o;
  o.p = 1.5;
  const absl::Status s = ValidateSparseIcpOptions(o);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("sicp.p"), std::string::npos);
}

}  // namespace
}  // namespace mlsreg
