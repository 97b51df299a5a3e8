// The automatic MLS radius: r from the noise estimated on the clouds (geometry/noise_estimate.h).
// The paper tunes r per experiment (Table 2: 5 d up to sigma = 0.8 d, 8 d at sigma = 2 d) and
// assumes the scanner's noise is known; mlsreg measures it instead. The rule r = max(5 d, k sigma)
// passes through both of the paper's settings and extends beyond 2 d; k is chosen on the tuning
// split (docs/evaluation.md).
#pragma once

#include <algorithm>

namespace mlsreg {

inline constexpr double kMinAutoMlsRadiusD = 5.0;
inline constexpr double kAutoMlsRadiusPerSigma = 4.0;
inline constexpr double kMaxAutoMlsRadiusD = 30.0;  // beyond: the clouds are more noise than shape

// `sigma_d`: the larger of the target's and the source's noise estimates, in units of d.
inline double AutoMlsRadiusD(double sigma_d) {
  return std::clamp(kAutoMlsRadiusPerSigma * sigma_d, kMinAutoMlsRadiusD, kMaxAutoMlsRadiusD);
}

}  // namespace mlsreg
