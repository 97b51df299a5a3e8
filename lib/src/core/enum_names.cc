#include "mlsreg/core/enum_names.h"

namespace mlsreg {

std::string_view EnumNames::NameOf(int value) const {
  for (const EnumValueName& v : values) {
    if (v.value == value) return v.name;
  }
  return "unknown";
}

std::string EnumNames::Choices(std::string_view separator) const {
  std::string out;
  for (const EnumValueName& v : values) {
    if (!out.empty()) out += separator;
    out += v.name;
  }
  return out;
}

absl::StatusOr<int> EnumNames::Parse(std::string_view name, std::string_view field) const {
  for (const EnumValueName& v : values) {
    if (v.name == name) return v.value;
  }
  return absl::InvalidArgumentError(std::string(field) + ": unknown value '" + std::string(name) +
                                    "' (known: " + Choices(", ") + ")");
}

}  // namespace mlsreg
