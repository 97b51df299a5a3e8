// Bookkeeping shared by the registration loops (Sparse ICP, G-ICP, FGR): timing, the RMSE of an
// iteration's correspondences, and recording an iteration (trace + observer).
#pragma once

#include <chrono>
#include <cmath>

#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg::internal {

using Clock = std::chrono::steady_clock;

inline double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// RMSE of the matched correspondences from their summed squared distances, absolute and in d.
inline void SetRmse(IterationReport& report, double sum_squared, double d) {
  if (report.counts.matched == 0) return;
  report.rmse = std::sqrt(sum_squared / report.counts.matched);
  report.rmse_d = report.rmse / d;
}

// Stamps the report with the pose after the iteration and the elapsed time, appends it to the
// trace and tells the observer.
inline void RecordIteration(RegistrationResult& result, IterationReport& report,
                            const RigidTransform& transform, const RegistrationCallbacks& callbacks,
                            Clock::time_point start) {
  report.transform = transform.matrix();
  report.elapsed_seconds = Seconds(start);
  result.trace.push_back(report);
  if (callbacks.on_iteration) callbacks.on_iteration(report);
}

// The caller's callbacks with every report stamped with its stage and candidate.
inline RegistrationCallbacks StampedCallbacks(const RegistrationCallbacks& callbacks, Stage stage,
                                              int candidate) {
  RegistrationCallbacks out;
  out.should_stop = callbacks.should_stop;
  if (callbacks.on_iteration) {
    out.on_iteration = [&callbacks, stage, candidate](const IterationReport& report) {
      IterationReport stamped = report;
      stamped.stage = stage;
      stamped.candidate = candidate;
      callbacks.on_iteration(stamped);
    };
  }
  return out;
}

inline void Stamp(RegistrationResult& result, Stage stage, int candidate) {
  for (IterationReport& report : result.trace) {
    report.stage = stage;
    report.candidate = candidate;
  }
}

}  // namespace mlsreg::internal
