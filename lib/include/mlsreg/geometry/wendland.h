// The Wendland weight of degree 5 used by the MLS surface (paper Eq. 6).
#pragma once

namespace mlsreg {

// theta_r(d) = (1 - d/r)^4 (1 + 4 d/r) for 0 <= d < r, else 0. C2-smooth, compact support r.
inline double WendlandWeight(double distance, double radius) {
  if (distance >= radius) return 0.0;
  const double x = distance / radius;
  const double a = 1.0 - x;
  const double a2 = a * a;
  return a2 * a2 * (1.0 + 4.0 * x);
}

}  // namespace mlsreg
