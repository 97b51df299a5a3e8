// Transforms on the wire: 16 row-major numbers, checked to be rigid on the way in.
#pragma once

#include <string_view>

#include "absl/status/statusor.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

void ToProto(const Matrix4& m, v1::Transform* out);
// 16 finite numbers forming a rigid transform; `field` names it in errors.
absl::StatusOr<Matrix4> FromProto(const v1::Transform& t, std::string_view field);
// A transform the server reported (not checked): the identity unless it has 16 numbers.
Matrix4 ReportedFromProto(const v1::Transform& t);

}  // namespace mlsreg::wire
