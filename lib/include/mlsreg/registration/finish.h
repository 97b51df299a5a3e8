// How method auto polishes the pose it chose: one rule from the clouds' measured noise.
//
// Every correspondence compares a source point with a model of the target's surface near it.
// - Plane-to-plane (G-ICP's step on the raw points) takes the target's points as they are: each
//   pair carries the noise of both clouds, and almost no bias (the planes span ~10 neighbours).
// - MLS fits a polynomial over the support radius (>= 5 d): the target's noise is averaged away,
//   but the fit departs from a surface that is not a polynomial at that scale (creases, the
//   facets of a mesh, a kerb) by a floor b that does not shrink with the noise.
// So MLS pays where the target's noise exceeds that floor, sigma > b, and plane-to-plane wins
// below it. The floor was measured on the tuning split as the crossover of the two finishes,
// each over every source point from near the truth (median RMSE/d, 48 problems per level):
//   sigma (estimated)   0 (0.10)   0.2 d (0.24)   0.4 d (0.43)   0.8 d (0.76)   2 d (1.53)
//   plane-to-plane      0.0046     0.029          0.072          0.19           0.81
//   MLS                 0.035      0.065          0.067          0.098          0.26
// Both finishes use every source point up to kFinishMaxSamples: the pose's standard error falls
// with the square root of the pairs, and the 2,000 random samples of the refinement were a
// floor of their own (0.023 d at sigma = 0, 0.14 d at 0.8 d).
#pragma once

#include "mlsreg/registration/result.h"

namespace mlsreg {

// The MLS fit's floor b in units of the target's d: the crossover above.
inline constexpr double kMlsFitFloorD = 0.35;
// The finish's source points: all of them up to this many (a random subset beyond).
inline constexpr int kFinishMaxSamples = 20000;

// `noise_d`: the larger of the clouds' noise estimates, units of the target's d.
inline FinishKind ChooseFinish(double noise_d) {
  return noise_d < kMlsFitFloorD ? FinishKind::kPlaneToPlane : FinishKind::kMls;
}

// Below this noise (units of the target's d) a voxel alignment that verifies goes straight to the
// finish, without MLS-SICP's refinement on the random samples first: the finish over every
// source point converges from there to a pose as close to the truth. Plane-to-plane's
// Gauss-Newton steps do at any noise (tuning split, sigma 0: the same median error, 14 % less
// time); so do Sparse ICP's lp steps with MLS at sigma = 0.8 d (estimated 0.73-0.79 d; median
// RMSE 0.0993 -> 0.0954 d, 48/48 verified; whole processes interleaved with the code before:
// 0.96 of the time, 13-14 % fewer instructions) and on KITTI and the tuning streets (estimated
// 0.26-0.52 d; 130 registrations: the same successes and verdicts, mean translation error
// 0.0285 -> 0.0284 m on KITTI; 0.99 of the time). At sigma = 2 d (estimated 1.47-1.67 d)
// they do not: from the voxel pose they end farther from the truth (median 0.260 -> 0.303 d),
// so the refinement stays above the threshold, set between the two levels.
inline constexpr double kRefineBeforeMlsFinishD = 1.0;
inline bool RefinesBeforeFinish(double noise_d) {
  return ChooseFinish(noise_d) == FinishKind::kMls && noise_d >= kRefineBeforeMlsFinishD;
}

// Whether the finish polishes a result with this verdict: a verified one, and a `pulled` one
// (right, but one small rigid step short of the data's optimum: the finish is that step). The
// polished pose is kept only when it verifies. On KITTI pair 10 -> 0 from the identity the
// refinement ended `pulled` (a step of 0.04 deg would remove 3.5 % of the residuals); polished,
// it verifies.
inline bool FinishPolishes(Verdict verdict) {
  return verdict == Verdict::kVerified || verdict == Verdict::kPulled;
}

}  // namespace mlsreg
