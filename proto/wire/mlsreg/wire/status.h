// Status codes across the wire: absl::Status in the library, grpc::Status on the wire (codes
// are numerically the same).
#pragma once

#include "absl/status/status.h"
#include "grpcpp/support/status.h"

namespace mlsreg::wire {

grpc::Status ToGrpcStatus(const absl::Status& status);
absl::Status ToAbslStatus(const grpc::Status& status);

}  // namespace mlsreg::wire
