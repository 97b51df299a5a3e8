// The ICP loop every iterative method runs: stop polling, iteration numbering across phases, the
// trace, the minimum-correspondence check and the stop rules. A method supplies an IcpStep (its
// match and solve); composite methods (ST-SICP, CP-SICP+MLS-SICP) run the loop more than once.
#pragma once

#include <functional>
#include <optional>
#include <span>

#include "loop_support.h"
#include "mlsreg/registration/result.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg::internal {

// One method's iteration, in two halves.
class IcpStep {
 public:
  virtual ~IcpStep() = default;
  // Finds and filters correspondences for the samples at `pose`, filling report.counts and the
  // RMSE. False when should_stop said stop part-way (the iteration is then abandoned).
  virtual bool Match(const RigidTransform& pose, IterationReport& report) = 0;
  // The increment from the last Match's correspondences (only called when enough of them were
  // accepted), or nullopt when the step is degenerate (the pose then stays). May set
  // report.admm_iterations.
  virtual std::optional<RigidTransform> Solve(IterationReport& report) = 0;
  // Where the samples are after Solve (the kRecentPoses rule measures motion from there).
  virtual std::span<const Vec3> moved_samples() const = 0;
  // The samples in the source frame (the kStepSize rule moves them by the increment).
  virtual std::span<const Vec3> samples() const = 0;
  // Coarse to fine: whether the correspondences are still in a coarse phase, which ends (Refine)
  // when the loop converges on them.
  virtual bool coarse() const { return false; }
  virtual void Refine() {}
};

enum class StopRule {
  // Sparse ICP's: the samples return to within the threshold of one of the last 8 poses (no
  // motion, or a cycle), or the last 8 poses all lie within `stall` of the current one.
  kRecentPoses,
  // G-ICP's: the increment moved no sample farther than the threshold.
  kStepSize,
};

struct LoopSettings {
  StopRule rule = StopRule::kRecentPoses;
  int max_iterations = 100;
  int min_correspondences = 6;
  double convergence = 0.0;         // absolute lengths
  double coarse_convergence = 0.0;  // while step.coarse()
  double stall = 0.0;               // 0 disables; not in a coarse phase
  double noise_stall = 0.0;         // 0 disables; both phases
  // Multiple of the pose's standard error rmse / sqrt(accepted) within which the recent poses
  // count as stalled (RMS over the samples); 0 disables; not in a coarse phase.
  double stall_standard_errors = 0.0;
  int iteration_offset = 0;  // reports are numbered after the iterations of earlier phases
  // The run also ends, converged, as soon as the pose satisfies this: it has reached a pose
  // known to lie where the run would converge. Empty: never.
  std::function<bool(const RigidTransform&)> reached;
};

// Runs the loop from `pose`, appending to result.trace and setting result.transform,
// termination, converged, iterations (of this run) and the matching and optimisation timings.
void RunIcpLoop(IcpStep& step, RigidTransform pose, const LoopSettings& settings,
                const RegistrationCallbacks& callbacks, Clock::time_point start,
                RegistrationResult& result);

}  // namespace mlsreg::internal
