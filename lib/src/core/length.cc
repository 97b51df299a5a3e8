#include "mlsreg/core/length.h"

#include <charconv>
#include <cmath>
#include <string>

#include "absl/strings/str_cat.h"

namespace mlsreg {
namespace {

// The units a length may be given in: their size in metres, or 0 for units of d.
struct LengthUnit {
  std::string_view suffix;
  double metres;
};
// Longest suffixes first: "mm" and "cm" before "m".
constexpr LengthUnit kUnits[] = {{"mm", 1e-3}, {"cm", 1e-2}, {"m", 1.0}, {"d", 0.0}};

std::string_view TrimTrailingSpaces(std::string_view text) {
  while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
  return text;
}

}  // namespace

absl::StatusOr<GivenLength> ParseLength(std::string_view text, std::string_view field) {
  std::string_view number = TrimTrailingSpaces(text);
  double scale = 0.0;  // units of d
  for (const LengthUnit& unit : kUnits) {
    if (!number.ends_with(unit.suffix)) continue;
    number = TrimTrailingSpaces(number.substr(0, number.size() - unit.suffix.size()));
    scale = unit.metres;
    break;
  }
  double value = 0.0;
  const char* end = number.data() + number.size();
  const auto [p, ec] = std::from_chars(number.data(), end, value);
  if (number.empty() || ec != std::errc() || p != end || !std::isfinite(value)) {
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(field), ": '", std::string(text),
                     "' is not a length: a number in units of d (20, 20d) or in m, cm or mm "
                     "(5m, 30cm, 5mm)"));
  }
  if (scale == 0.0) return GivenLength{value, false};
  return GivenLength{value * scale, true};
}

}  // namespace mlsreg
