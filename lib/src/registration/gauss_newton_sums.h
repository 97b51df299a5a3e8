// GaussNewtonSums: what a Gauss-Newton ICP step adds up over its pairs, the normal equations
// (sum J^T W J, sum J^T W r) with the squared residuals, and how many pairs were matched, too far
// or invalid. A step sums them over fixed blocks of samples on the threads (ParallelSum), so
// partial sums add to one another (Add), and the total goes into the iteration's report.
#pragma once

#include <Eigen/Core>

#include "loop_support.h"
#include "mlsreg/registration/result.h"

namespace mlsreg::internal {

struct GaussNewtonSums {
  Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  double sum_squared = 0.0;
  int matched = 0, too_far = 0, invalid = 0;

  void Add(const GaussNewtonSums& other) {
    h += other.h;
    g += other.g;
    sum_squared += other.sum_squared;
    matched += other.matched;
    too_far += other.too_far;
    invalid += other.invalid;
  }

  // The counts and the RMSE of the matched pairs (d: the target's sampling distance).
  void Report(IterationReport& report, double d) const {
    report.counts.matched += matched;
    report.counts.rejected_distance += too_far;
    report.counts.invalid += invalid;
    SetRmse(report, sum_squared, d);
  }
};

}  // namespace mlsreg::internal
