// EstimateNoise: the standard deviation of a scan's noise across its surface, in units of its
// sampling distance d, from the residuals of local quadric fits. The MLS radius follows from it
// (geometry/mls_radius.h), so that MLS-SICP de-noises as much as the data need.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

struct NoiseEstimate {
  double sigma_d = 0.0;       // estimated noise standard deviation along the normal, in units of d
  double fit_radius_d = 0.0;  // radius of the local fits of the last round
  int probes = 0;             // neighbourhoods that gave a fit in the last round
  bool stopped = false;       // should_stop said stop: nothing is usable
};

struct NoiseEstimateOptions {
  int probes = 256;  // random points whose neighbourhoods are fitted
  std::uint64_t seed = 7;
  // The fit radius starts here and grows to kRadiusPerSigma * sigma while the estimate says the
  // neighbourhood was too thin for the noise (a slab thicker than wide has no reliable plane).
  double min_fit_radius_d = 6.0;
  int max_rounds = 3;
};

// At `options.probes` points drawn from `candidates` (all points when empty), a Wendland-weighted
// quadratic height field is fitted over the weighted-PCA plane of the neighbours within the fit
// radius. Its weighted residual variance, corrected for the six fitted coefficients with the
// effective sample size (sum w)^2 / sum w^2, estimates sigma^2 there: a quadric absorbs the
// surface's curvature at that scale, so a smooth noise-free scan gives about 0. The median over
// the probes is robust to edges and creases. `d` is the cloud's sampling distance. Returns a
// zero estimate with probes = 0 when no neighbourhood can be fitted; stopped when should_stop
// (asked every 16 probes) said stop.
NoiseEstimate EstimateNoise(const std::vector<Vec3>& points, const KdTree& tree, double d,
                            std::span<const std::uint32_t> candidates = {},
                            const NoiseEstimateOptions& options = {},
                            const StopCheck& should_stop = {}, int threads = 1);

}  // namespace mlsreg
