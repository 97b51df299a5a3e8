#include "mlsreg/geometry/weighted_covariance.h"

#include <Eigen/Eigenvalues>

namespace mlsreg {
namespace {
// Relative size of the middle eigenvalue below which a neighbourhood counts as a line.
constexpr double kDegenerateRatio = 1e-10;
}  // namespace

bool WeightedCovariance::Finalize(LocalFrame& frame) const {
  if (count_ < 3 || !(sum_w_ > 0.0)) return false;
  const Vec3 mean_offset = sum_wd_ / sum_w_;
  const Eigen::Matrix3d covariance = sum_wdd_ / sum_w_ - mean_offset * mean_offset.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() != Eigen::Success) return false;
  Vec3 lambda = solver.eigenvalues().cwiseMax(0.0);
  if (!(lambda[2] > 0.0) || lambda[1] <= kDegenerateRatio * lambda[2]) return false;
  frame.mean = origin_ + mean_offset;
  frame.normal = solver.eigenvectors().col(0);
  frame.tangent_u = solver.eigenvectors().col(2);
  frame.tangent_v = frame.normal.cross(frame.tangent_u);  // right-handed (u, v, n)
  frame.eigenvalues = lambda;
  frame.surface_variation = lambda[0] / lambda.sum();
  return true;
}

}  // namespace mlsreg
