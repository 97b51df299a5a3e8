// The header of a Register call, built in one place for the client and the tests.
#pragma once

#include <optional>
#include <string>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

// The header of a Register call: target, method and every parameter, the initial transform,
// the ground truth when given, and the source's header; its packed data goes to `payload`
// (inline or in chunks: the caller decides).
void BuildRegisterHeader(const std::string& target_id, const PointCloud& source,
                         v1::ScalarType scalar_type, const RegistrationOptions& options,
                         const Matrix4& initial, const std::optional<Matrix4>& ground_truth,
                         v1::RegisterHeader* header, std::string* payload);

}  // namespace mlsreg::wire
