// What a registration reports: one IterationReport per ICP iteration (streamed through the
// callbacks), and the RegistrationResult at the end.
#pragma once

#include <functional>
#include <string_view>
#include <vector>

#include "mlsreg/core/enum_names.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/correspondences/correspondence_filter.h"

namespace mlsreg {
// Streamed once per ICP iteration.
struct IterationReport {
  int iteration = 0;                        // 1-based
  Matrix4 transform = Matrix4::Identity();  // after this iteration's update
  double rmse = 0.0;    // RMSE of this iteration's accepted correspondences (absolute units)
  double rmse_d = 0.0;  // the same in units of d
  CorrespondenceCounts counts;
  int admm_iterations = 0;
  double elapsed_seconds = 0.0;  // since Register was called
};

enum class Termination {
  kConverged,              // samples stopped moving, or alternate between two poses
  kMaxIterations,          // max_iterations reached
  kCancelled,              // should_stop returned true
  kTooFewCorrespondences,  // fewer than min_correspondences survived the filters
};
std::string_view TerminationName(Termination termination);  // "converged", ...
const EnumNames& TerminationNames();                        // wire enum "Termination"

// Wall time of the phases of paper Figure 6.
struct PhaseTimings {
  double preprocessing = 0.0;  // source analysis (the target's is cached in Target)
  double subsampling = 0.0;
  double matching = 0.0;      // correspondence search + filtering
  double optimisation = 0.0;  // Sparse ICP ADMM
  double total = 0.0;
};

struct RegistrationResult {
  Matrix4 transform = Matrix4::Identity();  // maps source points into the target frame
  bool converged = false;
  Termination termination = Termination::kMaxIterations;
  int iterations = 0;
  std::vector<IterationReport> trace;
  PhaseTimings timings;
  double sampling_distance = 0.0;  // the target's d, the unit of every *_d field
  int num_samples = 0;
  // Methods that read the MLS parameters: the support radius used (units of d), whether it was
  // chosen automatically, and the noise estimates it was chosen from (units of d; 0 when not
  // estimated: an explicit radius needs none).
  double mls_radius_d = 0.0;
  bool mls_radius_auto = false;
  double target_noise_d = 0.0;
  double source_noise_d = 0.0;
};

struct RegistrationCallbacks {
  std::function<void(const IterationReport&)> on_iteration;  // may be empty
  std::function<bool()> should_stop;  // polled once per iteration; true cancels (may be empty)
};

}  // namespace mlsreg
