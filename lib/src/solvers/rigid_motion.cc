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

RigidTransform TwistIncrementAbout(const Eigen::Matrix<double, 6, 1>& omega_v, const Vec3& centre) {
  RigidTransform step = RigidTransform::Identity();
  step.linear() = ExpSo3(omega_v.head<3>());
  step.translation() = centre - step.linear() * centre + omega_v.tail<3>();
  return step;
}

RigidTransform TwistIncrement(const Eigen::Matrix<double, 6, 1>& omega_v) {
  return TwistIncrementAbout(omega_v, Vec3::Zero());
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
  // Rotations in units of `lever` (omega = omega' / lever): h' = S h S, rhs' = S rhs and
  // step = S step' with S = diag(1 / lever, 1).
  const double rotation_trace = h.topLeftCorner<3, 3>().trace();
  const double translation_trace = h.bottomRightCorner<3, 3>().trace();
  const double lever = rotation_trace > 0.0 && translation_trace > 0.0
                           ? std::sqrt(rotation_trace / translation_trace)
                           : 1.0;
  Vector6 scale = Vector6::Ones();
  scale.head<3>().setConstant(1.0 / lever);
  const Eigen::Matrix<double, 6, 6> balanced = scale.asDiagonal() * h * scale.asDiagonal();
  const Vector6 balanced_rhs = scale.cwiseProduct(rhs);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(balanced);
  if (eigen.info() != Eigen::Success) return step;
  const Vector6& values = eigen.eigenvalues();  // ascending
  if (!(values[5] > 0.0)) return step;
  for (int k = 0; k < 6; ++k) {
    if (values[k] <= kRelativeRank * values[5]) continue;
    const auto direction = eigen.eigenvectors().col(k);
    step.noalias() += (direction.dot(balanced_rhs) / values[k]) * direction;
  }
  return scale.cwiseProduct(step);
}

RigidTransform PointToPlaneMotion(std::span<const Vec3> x, std::span<const Vec3> y,
                                  std::span<const Vec3> n, std::span<const double> u,
                                  std::span<const double> w, double tangential_weight) {
  Vec3 mean;
  if (!WeightedCentroid(x, w, mean)) return RigidTransform::Identity();
  PointToPlaneSums sums;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (w[i] <= 0.0) continue;
    sums.Add(x[i] - mean, x[i] - y[i], n[i], u[i], w[i], tangential_weight);
  }
  return sums.Solve(mean);
}

// With J = d(R x + t)/d(omega, t) = [-[xc]x  I] and P = I - n n^T, the tangential term adds
// lambda w J^T P J to the normal matrix and lambda w J^T P e to the right side (e = x - y).
// Since J^T n is the point-to-plane row r = (xc x n, n):
//   J^T P J = J^T J - r r^T,   J^T P e = J^T e - r (n . e),   J^T e = (xc x e, e),
// and the sum of J^T J needs only the weighted moments of xc (accumulated below):
//   sum lambda w J^T J = [ q I - M   [s]x ]    s = sum lambda w xc, M = sum lambda w xc xc^T,
//                        [ -[s]x    s0 I  ]    q = trace(M), s0 = sum lambda w,
// where s = lambda sum w xc vanishes: xc is taken about the w-weighted centroid.
void PointToPlaneSums::Add(const Vec3& xc, const Vec3& e, const Vec3& n, double u, double w,
                           double tangential_weight) {
  Eigen::Matrix<double, 6, 1> row;
  row.head<3>() = xc.cross(n);
  row.tail<3>() = n;
  const double along = e.dot(n);
  const double tangential = w * tangential_weight;
  // w r r^T for the plane, minus lambda w r r^T of the tangential term, in one update.
  const double plane_weight = w - tangential;
  for (int j = 0; j < 6; ++j) {
    const double scaled = plane_weight * row[j];
    for (int k = j; k < 6; ++k) lhs(k, j) += scaled * row[k];
  }
  rhs.noalias() -= (w * (along - u) - tangential * along) * row;
  if (tangential > 0.0) {
    tangential_total += tangential;
    for (int j = 0; j < 3; ++j) {
      for (int k = j; k < 3; ++k) moments(k, j) += tangential * xc[k] * xc[j];
    }
    rhs.head<3>() -= tangential * xc.cross(e);
    rhs.tail<3>() -= tangential * e;
  }
  ++count;
}

void PointToPlaneSums::Merge(const PointToPlaneSums& other) {
  lhs += other.lhs;
  rhs += other.rhs;
  moments += other.moments;
  tangential_total += other.tangential_total;
  count += other.count;
}

RigidTransform PointToPlaneSums::Solve(const Vec3& centre) const {
  using Matrix6 = Eigen::Matrix<double, 6, 6>;
  using Vector6 = Eigen::Matrix<double, 6, 1>;
  RigidTransform result = RigidTransform::Identity();
  if (count == 0) return result;
  Matrix6 lower = lhs;
  if (tangential_total > 0.0) {
    const double q = moments.trace();
    for (int j = 0; j < 3; ++j) {
      for (int k = j; k < 3; ++k) lower(k, j) += (k == j ? q : 0.0) - moments(k, j);
      lower(j + 3, j + 3) += tangential_total;
    }
  }
  const Matrix6 full = lower.selfadjointView<Eigen::Lower>();
  const Vector6 step = SolveConstrainedStep(full, rhs);
  // x' = R (x - centre) + centre + t
  const Eigen::Matrix3d rotation = ExpSo3(step.head<3>());
  result.linear() = rotation;
  result.translation() = centre + step.tail<3>() - rotation * centre;
  return result;
}

}  // namespace mlsreg
