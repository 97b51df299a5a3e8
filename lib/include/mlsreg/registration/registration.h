// Registration: the one entry point the CLI, the evaluation harness and the server call.
#pragma once

#include <optional>

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg {

// How a registration runs, as opposed to what it computes: the result is the same for any value.
struct ExecutionOptions {
  // Threads that split the correspondence search, the source analysis and ST-SICP's smoothing
  // (G-ICP and FGR run on one). should_stop is then called from several threads.
  int threads = 1;
};

// Registers `source` to `target` starting from `initial` (source -> target, rigid). Invalid input
// (bad cloud, non-rigid initial transform, options out of range) gives InvalidArgument naming the
// field; a registration that runs always returns a result, whatever its termination.
absl::StatusOr<RegistrationResult> Register(const Target& target, const PointCloud& source,
                                            const Matrix4& initial,
                                            const RegistrationOptions& options,
                                            const RegistrationCallbacks& callbacks = {},
                                            const ExecutionOptions& execution = {});

// The verdict Register gives a result of any method, for a pose given by the caller: `transform`
// (source -> target) scored on the source's voxel samples (VerifyPose, the source's noise
// estimated) and, when it verifies on little information along its weakest direction, searched
// for a rival (the verdict is then `ambiguous`; docs/verification.md, "Rivals") as far as the
// rivals of a global stage's result: the pose may come from anywhere.
struct PoseVerdict {
  VerificationScore score;
  std::optional<AutoCandidate> rival;
};
PoseVerdict VerifyPoseSearchingRivals(const Target& target, const PointCloud& source,
                                      const Matrix4& transform, int threads = 1);

}  // namespace mlsreg
