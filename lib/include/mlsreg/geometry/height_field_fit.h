// HeightFieldFit: weighted least-squares bivariate polynomial f = g(x, y) over a reference plane.
#pragma once

#include <Eigen/Core>
#include <array>

namespace mlsreg {

// The fitted polynomial g(x, y) = sum c_k m_k(x, y) with monomials, in this order,
// 1, x, y, x^2, xy, y^2, x^3, x^2 y, x y^2, y^3 (the first (deg+1)(deg+2)/2 are used).
struct HeightField {
  int degree = 0;
  std::array<double, 10> coefficients{};

  double ValueAtOrigin() const { return coefficients[0]; }
  // Partial derivatives at the origin (zero for degree 0).
  double SlopeX() const { return coefficients[1]; }
  double SlopeY() const { return coefficients[2]; }
  double Evaluate(double x, double y) const;
};

constexpr int kMaxHeightFieldDegree = 3;
constexpr double kSamplesPerCoefficient = 2.0;
constexpr int MonomialCount(int degree) { return (degree + 1) * (degree + 2) / 2; }

// Accumulate weighted samples (x, y, f), then Finalize. Coordinates should be scaled to O(1)
// (e.g. divided by the support radius) for conditioning. Finalize uses the requested degree only
// when the neighbourhood supports it: the effective sample size (sum w)^2 / sum w^2 must be at
// least kSamplesPerCoefficient times the number of coefficients, and the system well conditioned;
// otherwise it falls back to lower degrees. (A cubic through 20 scan-line samples extrapolates
// wildly; sparse real scans need this.) No heap allocation.
class HeightFieldFit {
 public:
  explicit HeightFieldFit(int degree);

  // Inline: the fits call it once per neighbour, the MLS patches' hottest loop.
  void Add(double x, double y, double f, double weight) {
    double xp[7], yp[7];
    xp[0] = yp[0] = 1.0;
    for (int k = 1; k < 7; ++k) {
      xp[k] = xp[k - 1] * x;
      yp[k] = yp[k - 1] * y;
    }
    for (int a = 0; a <= 6; ++a) {
      const double wx = weight * xp[a];
      for (int b = 0; a + b <= 6; ++b) moments_[a][b] += wx * yp[b];
    }
    const double wf = weight * f;
    for (int a = 0; a <= 3; ++a) {
      const double wfx = wf * xp[a];
      for (int b = 0; a + b <= 3; ++b) rhs_moments_[a][b] += wfx * yp[b];
    }
    ++count_;
    sum_w_ += weight;
    sum_w2_ += weight * weight;
  }

  // False only if even degree 0 cannot be fitted (no positive weight).
  bool Finalize(HeightField& out) const;

 private:
  int degree_;
  int count_ = 0;
  double sum_w_ = 0.0;
  double sum_w2_ = 0.0;
  // The normal matrix of monomials up to degree 3 only holds the 28 weighted moments
  // sum w x^a y^b with a + b <= 6, and the right-hand side the 10 moments sum w f x^a y^b with
  // a + b <= 3: accumulating those takes ~1.9x fewer instructions than the 10x10 matrix.
  double moments_[7][7] = {};
  double rhs_moments_[4][4] = {};
};

}  // namespace mlsreg
