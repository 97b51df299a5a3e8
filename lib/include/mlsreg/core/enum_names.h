// EnumNames: one table per enum of the registration options, giving each value the name that
// the CLI, reports and error messages use and the suffix of its wire enum value (the wire enum
// value is <wire_prefix><wire_suffix>, e.g. FAR_QUERY_POLICY_SEED). proto/wire maps enums through
// these tables by name, and a test checks every row against the proto descriptor.
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace mlsreg {

struct EnumValueName {
  int value;                     // static_cast<int> of the library enum
  std::string_view name;         // "seed-until-converged"
  std::string_view wire_suffix;  // "SEED_UNTIL_CONVERGED"
};

struct EnumNames {
  std::string_view wire_enum;    // the proto enum's name in package mlsreg.v1, "FarQueryPolicy"
  std::string_view wire_prefix;  // "FAR_QUERY_POLICY_"; <prefix>UNSPECIFIED means the default
  std::span<const EnumValueName> values;

  // The value's name; "unknown" for a value outside the table.
  std::string_view NameOf(int value) const;
  // "a | b | c", for help texts.
  std::string Choices(std::string_view separator = " | ") const;
  // The value named `name`; INVALID_ARGUMENT naming `field` and listing the known names.
  absl::StatusOr<int> Parse(std::string_view name, std::string_view field) const;
};

template <typename Enum>
std::string_view NameOf(const EnumNames& names, Enum value) {
  return names.NameOf(static_cast<int>(value));
}

template <typename Enum>
absl::StatusOr<Enum> ParseEnum(const EnumNames& names, std::string_view name,
                               std::string_view field) {
  absl::StatusOr<int> value = names.Parse(name, field);
  if (!value.ok()) return value.status();
  return static_cast<Enum>(*value);
}

}  // namespace mlsreg
