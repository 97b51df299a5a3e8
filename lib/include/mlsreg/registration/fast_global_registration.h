// Fast Global Registration (Zhou, Park, Koltun 2016): the paper's FGR comparator. Global: it
// ignores the initial transform.
#pragma once

#include <chrono>

#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg {

// FPFH on `fgr.samples` random samples of each cloud (radius fgr.feature_radius_d), mutual
// nearest neighbours in feature space, the tuple test (tau = 0.95, at most 1000 tuples), then 64
// Gauss-Newton steps of a Geman-McClure objective with graduated non-convexity (mu divided by
// 1.4 every 4 steps down to the maximum correspondence distance). One report per Gauss-Newton
// step: matched = correspondences within the current scale, rmse over those.
RegistrationResult RunFastGlobalRegistration(const Target& target, const PointCloud& source,
                                             const RegistrationOptions& options,
                                             const RegistrationCallbacks& callbacks,
                                             std::chrono::steady_clock::time_point start);

}  // namespace mlsreg
