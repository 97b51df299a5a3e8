#include "mlsreg/geometry/height_field_fit.h"

#include <Eigen/Cholesky>
#include <algorithm>

namespace mlsreg {
namespace {

// Reciprocal condition number below which a degree is abandoned for the next lower one.
constexpr double kMinRcond = 1e-10;

Eigen::Matrix<double, 10, 1> Monomials(double x, double y) {
  Eigen::Matrix<double, 10, 1> m;
  m << 1.0, x, y, x * x, x * y, y * y, x * x * x, x * x * y, x * y * y, y * y * y;
  return m;
}

template <int N>
bool SolveLeading(const Eigen::Matrix<double, 10, 10>& a, const Eigen::Matrix<double, 10, 1>& b,
                  std::array<double, 10>& coefficients) {
  const Eigen::Matrix<double, N, N> block = a.template topLeftCorner<N, N>();
  const Eigen::LDLT<Eigen::Matrix<double, N, N>> ldlt(block);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > kMinRcond)) return false;
  const Eigen::Matrix<double, N, 1> c = ldlt.solve(b.template head<N>());
  if (!c.allFinite()) return false;
  coefficients.fill(0.0);
  for (int k = 0; k < N; ++k) coefficients[k] = c[k];
  return true;
}

}  // namespace

double HeightField::Evaluate(double x, double y) const {
  return Monomials(x, y).dot(Eigen::Map<const Eigen::Matrix<double, 10, 1>>(coefficients.data()));
}

HeightFieldFit::HeightFieldFit(int degree)
    : degree_(std::clamp(degree, 0, kMaxHeightFieldDegree)) {}

bool HeightFieldFit::Finalize(HeightField& out) const {
  // Exponents (of x, of y) of the monomials, in HeightField order.
  static constexpr int kPowX[10] = {0, 1, 0, 2, 1, 0, 3, 2, 1, 0};
  static constexpr int kPowY[10] = {0, 0, 1, 0, 1, 2, 0, 1, 2, 3};
  Eigen::Matrix<double, 10, 10> a;
  Eigen::Matrix<double, 10, 1> rhs;
  for (int k = 0; k < 10; ++k) {
    for (int l = 0; l < 10; ++l) a(k, l) = moments_[kPowX[k] + kPowX[l]][kPowY[k] + kPowY[l]];
    rhs[k] = rhs_moments_[kPowX[k]][kPowY[k]];
  }
  const double effective_samples = sum_w2_ > 0.0 ? sum_w_ * sum_w_ / sum_w2_ : 0.0;
  for (int degree = degree_; degree >= 0; --degree) {
    const int coefficients = MonomialCount(degree);
    if (count_ < coefficients) continue;
    if (degree > 0 && effective_samples < kSamplesPerCoefficient * coefficients) continue;
    bool solved = false;
    switch (degree) {
      case 3:
        solved = SolveLeading<10>(a, rhs, out.coefficients);
        break;
      case 2:
        solved = SolveLeading<6>(a, rhs, out.coefficients);
        break;
      case 1:
        solved = SolveLeading<3>(a, rhs, out.coefficients);
        break;
      default:
        solved = SolveLeading<1>(a, rhs, out.coefficients);
        break;
    }
    if (solved) {
      out.degree = degree;
      return true;
    }
  }
  return false;
}

}  // namespace mlsreg
