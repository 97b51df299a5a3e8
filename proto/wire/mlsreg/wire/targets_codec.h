// Targets on the wire: TargetInfo <-> v1::Target.
#pragma once

#include "mlsreg/geometry/target_info.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

void ToProto(const TargetInfo& info, v1::Target* out);
TargetInfo FromProto(const v1::Target& target);

}  // namespace mlsreg::wire
