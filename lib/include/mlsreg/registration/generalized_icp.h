// Generalized ICP (Segal, Haehnel, Thrun 2009), plane-to-plane: the paper's G-ICP comparator.
#pragma once

#include <chrono>

#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg {

// Per point, the covariance of its k nearest neighbours with eigenvalues replaced by
// (epsilon, 1, 1) (plane-to-plane regularisation). False when fewer than 3 neighbours exist or
// the neighbourhood is degenerate.
bool PlaneCovariance(const std::vector<Vec3>& points, const KdTree& tree, const Vec3& at, int k,
                     double epsilon, Eigen::Matrix3d& covariance);

// The G-ICP loop: closest-point correspondences within gicp.max_distance_d, one Gauss-Newton step
// of sum e^T (C_target + R C_source R^T)^-1 e per ICP iteration (exact SO(3) update), until no
// sample moves more than convergence_d. Called by Register for Method::kGicp; inputs validated
// there. Reports count matched / rejected_distance / invalid (no covariance).
RegistrationResult RunGeneralizedIcp(const Target& target, const PointCloud& source,
                                     const Matrix4& initial, const RegistrationOptions& options,
                                     const RegistrationCallbacks& callbacks,
                                     std::chrono::steady_clock::time_point start);

}  // namespace mlsreg
