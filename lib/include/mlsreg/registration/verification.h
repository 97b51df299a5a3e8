// Verification: how well a pose lays a source onto the target's MLS surface, the score that
// picks among candidate poses and says whether a registration can be trusted.
#pragma once

#include <vector>

#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg {

struct VerificationOptions {
  // A sample agrees when its MLS projection onto the target lies within
  // max(inlier_distance_d, inlier_noise_factor * noise) * d of it...
  double inlier_distance_d = 3.0;
  double inlier_noise_factor = 3.0;
  // ...and its normal and the surface's make an angle with cosine at least this (the sign counts
  // when both clouds' normals are oriented toward their scanners).
  double min_normal_dot = 0.7;
};

struct VerificationScore {
  int samples = 0;                 // source samples tried
  int inliers = 0;                 // samples that agree
  double inlier_fraction = 0.0;    // inliers / samples: the score (share of the source explained)
  double rmse_d = 0.0;             // RMSE of the agreeing samples' distances, units of d
  double inlier_distance_d = 0.0;  // the distance within which a sample agrees, units of d
};

// Residuals of a real fit concentrate near the surface; a chance overlap of two different shapes
// spreads them across the band (a uniform spread has an RMS of 0.58 of its half-width).
inline constexpr double kMaxVerifiedRmsePerInlierDistance = 0.4;

// Whether a score says the pose is right: at least `min_inlier_fraction` of the source agrees,
// and the agreeing samples' RMSE is at most kMaxVerifiedRmsePerInlierDistance of the band.
bool IsVerified(const VerificationScore& score, double min_inlier_fraction);

// The distance of each of `points` (in the target's frame) to the target's MLS surface: to its
// projection by the target's MLS patches, or to the nearest target sample where no patch reaches
// (or the target has none). Absolute units.
std::vector<double> DistancesToMlsSurface(const Target& target, const std::vector<Vec3>& points);

// Scores `transform` (source to target) by the source samples `points` with unit `normals`
// (oriented toward the source's scanner when `oriented`). The target's MLS patches give the
// surface; a target without them is scored against its nearest samples. `noise_d` is the
// clouds' estimated noise (units of d). Allocation-free, thread-safe.
VerificationScore VerifyAlignment(const Target& target, const std::vector<Vec3>& points,
                                  const std::vector<Vec3>& normals, bool oriented,
                                  const Matrix4& transform, double noise_d,
                                  const VerificationOptions& options = {});

}  // namespace mlsreg
