#include "mlsreg/solvers/rigid_motion.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>

namespace mlsreg {

Eigen::Matrix3d ExpSo3(const Vec3& omega) {
  const double angle = omega.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
}

RigidTransform TwistIncrement(const Eigen::Matrix<double, 6, 1>& omega_v) {
  RigidTransform step = RigidTransform::Identity();
  step.linear() = ExpSo3(omega_v.head<3>());
  step.translation() = omega_v.tail<3>();
  return step;
}

namespace {
// Weighted centroid of the entries with positive weight; false when the total weight is zero.
bool WeightedCentroid(std::span<const Vec3> x, std::span<const double> w, Vec3& centroid) {
  double total = 0.0;
  Vec3 sum = Vec3::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (w[i] <= 0.0) continue;
    total += w[i];
    sum += w[i] * x[i];
  }
  if (!(total > 0.0)) return false;
  centroid = sum / total;
  return true;
}
}  // namespace

RigidTransform PointToPointMotion(std::span<const Vec3> x, std::span<const Vec3> y,
                                  std::span<const double> w) {
  RigidTransform result = RigidTransform::Identity();
  Vec3 cx, cy;
  if (!WeightedCentroid(x, w, cx) || !WeightedCentroid(y, w, cy)) return result;
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (w[i] <= 0.0) continue;
    cross.noalias() += w[i] * (x[i] - cx) * (y[i] - cy).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d correction = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0) correction(2, 2) = -1.0;
  const Eigen::Matrix3d rotation = svd.matrixV() * correction * svd.matrixU().transpose();
  result.linear() = rotation;
  result.translation() = cy - rotation * cx;
  return result;
}

Eigen::Matrix<double, 6, 1> SolveConstrainedStep(const Eigen::Matrix<double, 6, 6>& h,
                                                 const Eigen::Matrix<double, 6, 1>& rhs) {
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  constexpr double kRelativeRank = 1e-9;  // far above round-off (1e-16), far below real data
  Vector6 step = Vector6::Zero();
  if (!h.allFinite() || !rhs.allFinite()) return step;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(h);
  if (eigen.info() != Eigen::Success) return step;
  const Vector6& values = eigen.eigenvalues();  // ascending
  if (!(values[5] > 0.0)) return step;
  for (int k = 0; k < 6; ++k) {
    if (values[k] <= kRelativeRank * values[5]) continue;
    const auto direction = eigen.eigenvectors().col(k);
    step.noalias() += (direction.dot(rhs) / values[k]) * direction;
  }
  return step;
}

RigidTransform PointToPlaneMotion(std::span<const Vec3> x, std::span<const Vec3> y,
                                  std::span<const Vec3> n, std::span<const double> u,
                                  std::span<const double> w, double tangential_weight) {
  RigidTransform result = RigidTransform::Identity();
  Vec3 mean;
  if (!WeightedCentroid(x, w, mean)) return result;
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  Matrix6 lhs = Matrix6::Zero();
  Vector6 rhs = Vector6::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (w[i] <= 0.0) continue;
    const Vec3 xc = x[i] - mean;
    Vector6 row;
    row.head<3>() = xc.cross(n[i]);
    row.tail<3>() = n[i];
    const double residual = (x[i] - y[i]).dot(n[i]) - u[i];
    // The lower triangle += w row row^T, column by column: Eigen's rankUpdate arithmetic (the
    // same bits), inlined (the library call did not inline and showed in profiles).
    for (int j = 0; j < 6; ++j) {
      const double scaled = w[i] * row[j];
      for (int k = j; k < 6; ++k) lhs(k, j) += scaled * row[k];
    }
    rhs.noalias() -= (w[i] * residual) * row;
    if (tangential_weight > 0.0) {
      // d(R x + t)/d(omega, t) = [-[xc]x  I]; project residual and Jacobian onto the tangent plane.
      const Eigen::Matrix3d tangent = Eigen::Matrix3d::Identity() - n[i] * n[i].transpose();
      Eigen::Matrix<double, 3, 6> jacobian;
      jacobian.leftCols<3>() << 0.0, xc.z(), -xc.y(), -xc.z(), 0.0, xc.x(), xc.y(), -xc.x(), 0.0;
      jacobian.rightCols<3>().setIdentity();
      const Eigen::Matrix<double, 3, 6> projected = tangent * jacobian;
      const double weight = w[i] * tangential_weight;
      lhs.noalias() += weight * (projected.transpose() * projected);
      rhs.noalias() -= weight * (projected.transpose() * (tangent * (x[i] - y[i])));
    }
  }
  const Matrix6 full = lhs.selfadjointView<Eigen::Lower>();
  const Vector6 step = SolveConstrainedStep(full, rhs);
  // x' = R (x - mean) + mean + t
  const Eigen::Matrix3d rotation = ExpSo3(step.head<3>());
  result.linear() = rotation;
  result.translation() = mean + step.tail<3>() - rotation * mean;
  return result;
}

}  // namespace mlsreg
