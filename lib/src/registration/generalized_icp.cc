#include "mlsreg/registration/generalized_icp.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "loop_support.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg {
namespace {

using internal::Clock;
using internal::Seconds;

Eigen::Matrix3d Skew(const Vec3& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}

}  // namespace

bool PlaneCovariance(const std::vector<Vec3>& points, const KdTree& tree, const Vec3& at, int k,
                     double epsilon, Eigen::Matrix3d& covariance) {
  constexpr int kMaxNeighbors = 64;
  std::uint32_t indices[kMaxNeighbors];
  double d2[kMaxNeighbors];
  const std::size_t found = tree.Knn(at, std::min(k, kMaxNeighbors), indices, d2);
  if (found < 3) return false;
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < found; ++i) mean += points[indices[i]];
  mean /= static_cast<double>(found);
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < found; ++i) {
    const Vec3 d = points[indices[i]] - mean;
    c.noalias() += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(c);
  if (solver.info() != Eigen::Success || !(solver.eigenvalues()[1] > 0.0)) return false;
  const Eigen::Matrix3d& v = solver.eigenvectors();
  covariance = v * Vec3(epsilon, 1.0, 1.0).asDiagonal() * v.transpose();
  return true;
}

RegistrationResult RunGeneralizedIcp(const Target& target, const PointCloud& source,
                                     const Matrix4& initial, const RegistrationOptions& options,
                                     const RegistrationCallbacks& callbacks,
                                     Clock::time_point start) {
  RegistrationResult result;
  const double d = target.sampling_distance();
  result.sampling_distance = d;
  const GicpParams& p = options.gicp;

  Clock::time_point phase = Clock::now();
  const std::vector<std::uint32_t> indices =
      RandomSubsample(source.size(), static_cast<std::size_t>(options.num_samples), options.seed);
  result.num_samples = static_cast<int>(indices.size());
  result.timings.subsampling = Seconds(phase);

  // Source covariances at the samples.
  phase = Clock::now();
  const KdTree source_tree(source.points);
  const std::size_t m = indices.size();
  std::vector<Vec3> samples(m);
  std::vector<Eigen::Matrix3d> source_cov(m);
  std::vector<std::uint8_t> source_ok(m);
  for (std::size_t i = 0; i < m; ++i) {
    samples[i] = source.points[indices[i]];
    source_ok[i] = PlaneCovariance(source.points, source_tree, samples[i], p.covariance_neighbors,
                                   p.epsilon, source_cov[i]);
  }
  result.timings.preprocessing = Seconds(phase);

  // Target covariances, computed the first time a target point is matched.
  const std::vector<Vec3>& target_points = target.points();
  std::vector<Eigen::Matrix3d> target_cov;
  std::vector<std::int8_t> target_state(target_points.size(), -1);  // -1 unknown, 0 bad, 1 ok
  target_cov.resize(target_points.size());

  RigidTransform transform(Orthonormalize(initial));
  const double max_distance_squared = std::pow(p.max_distance_d * d, 2);
  const double convergence = options.convergence_d * d;
  result.termination = Termination::kMaxIterations;
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    if (callbacks.should_stop && callbacks.should_stop()) {
      result.termination = Termination::kCancelled;
      break;
    }
    phase = Clock::now();
    IterationReport report;
    report.iteration = iteration;
    Matrix6 h = Matrix6::Zero();
    Vector6 g = Vector6::Zero();
    double sum_squared = 0.0;
    const Eigen::Matrix3d r = transform.linear();
    for (std::size_t i = 0; i < m; ++i) {
      const Vec3 x = transform * samples[i];
      const Neighbor nn = target.tree().Nearest(x);
      if (!source_ok[i]) {
        ++report.counts.invalid;
        continue;
      }
      if (nn.distance_squared > max_distance_squared) {
        ++report.counts.rejected_distance;
        continue;
      }
      std::int8_t& state = target_state[nn.index];
      if (state < 0) {
        state = PlaneCovariance(target_points, target.tree(), target_points[nn.index],
                                p.covariance_neighbors, p.epsilon, target_cov[nn.index])
                    ? 1
                    : 0;
      }
      if (state == 0) {
        ++report.counts.invalid;
        continue;
      }
      const Eigen::Matrix3d combined = target_cov[nn.index] + r * source_cov[i] * r.transpose();
      const Eigen::Matrix3d information = combined.inverse();
      const Vec3 e = target_points[nn.index] - x;  // residual after x' = exp(delta) x
      Eigen::Matrix<double, 3, 6> jacobian;        // de/d(omega, v) = [ [x]x, -I ]
      jacobian.leftCols<3>() = Skew(x);
      jacobian.rightCols<3>() = -Eigen::Matrix3d::Identity();
      h.noalias() += jacobian.transpose() * information * jacobian;
      g.noalias() += jacobian.transpose() * information * e;
      sum_squared += e.squaredNorm();
      ++report.counts.matched;
    }
    internal::SetRmse(report, sum_squared, d);
    result.timings.matching += Seconds(phase);

    bool converged = false;
    if (report.counts.matched >= options.min_correspondences) {
      phase = Clock::now();
      const Vector6 delta = SolveConstrainedStep(h, -g);
      if (delta.allFinite()) {
        const RigidTransform step = TwistIncrement(delta);
        double max_move = 0.0;
        for (const Vec3& s : samples) {
          const Vec3 x = transform * s;
          max_move = std::max(max_move, (step * x - x).squaredNorm());
        }
        transform = step * transform;
        converged = std::sqrt(max_move) < convergence;
      }
      result.timings.optimisation += Seconds(phase);
    }
    result.iterations = iteration;
    internal::RecordIteration(result, report, transform, callbacks, start);
    if (report.counts.matched < options.min_correspondences) {
      result.termination = Termination::kTooFewCorrespondences;
      break;
    }
    if (converged) {
      result.termination = Termination::kConverged;
      result.converged = true;
      break;
    }
  }
  result.transform = transform.matrix();
  result.timings.total = Seconds(start);
  return result;
}

}  // namespace mlsreg
