#include "mlsreg/geometry/target_info.h"

namespace mlsreg {

const EnumNames& TargetStateNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(TargetState::kReady), "ready", "READY"},
      {static_cast<int>(TargetState::kStored), "stored", "STORED"},
  };
  static constexpr EnumNames kNames{"TargetState", "TARGET_STATE_", kValues};
  return kNames;
}

}  // namespace mlsreg
