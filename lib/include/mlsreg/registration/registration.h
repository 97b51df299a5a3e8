// Registration: the one entry point the CLI, the evaluation harness and the server call.
#pragma once

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg {

// Registers `source` to `target` starting from `initial` (source -> target, rigid). Invalid input
// (bad cloud, non-rigid initial transform, options out of range) gives InvalidArgument naming the
// field; a registration that runs always returns a result, whatever its termination.
absl::StatusOr<RegistrationResult> Register(const Target& target, const PointCloud& source,
                                            const Matrix4& initial,
                                            const RegistrationOptions& options,
                                            const RegistrationCallbacks& callbacks = {});

}  // namespace mlsreg
