// Library enums <-> wire enums, through the library's enum-name tables (EnumNames): a library
// value maps to the wire value named <wire_prefix><wire_suffix> in the proto descriptor, so no
// enum is mapped by a hand-written switch.
#pragma once

#include <string_view>

#include "absl/status/statusor.h"
#include "mlsreg/core/enum_names.h"

namespace mlsreg::wire {

// The wire number of a library value; 0 (UNSPECIFIED) when the table or the proto lacks it.
int EnumToWire(const EnumNames& names, int value);

// The library value of a wire number: `unspecified` for 0, else the table's row for the wire
// value's name. INVALID_ARGUMENT "<field>: unknown value N" for a number the proto does not
// define.
absl::StatusOr<int> EnumFromWire(const EnumNames& names, int wire_value, int unspecified,
                                 std::string_view field);

template <typename Enum>
absl::StatusOr<Enum> EnumFromWire(const EnumNames& names, int wire_value, Enum unspecified,
                                  std::string_view field) {
  absl::StatusOr<int> v = EnumFromWire(names, wire_value, static_cast<int>(unspecified), field);
  if (!v.ok()) return v.status();
  return static_cast<Enum>(*v);
}

}  // namespace mlsreg::wire
