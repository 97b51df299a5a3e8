// A length as a user writes it: a multiple of d, the target's mean nearest-neighbour spacing
// ("20", "20d"), or in the clouds' own units read as metres ("5m", "30cm", "5mm"). Lengths in d
// follow the sampling (the same flag fits a statue and a street scanned alike); lengths in metres
// follow the scene (a street's 5 m is 5 m however densely the sensor samples near itself).
#pragma once

#include <string_view>

#include "absl/status/statusor.h"

namespace mlsreg {

struct GivenLength {
  double value = 0.0;
  bool absolute = false;  // value in the clouds' units (metres), else in units of d

  // In the clouds' units, for a cloud whose d is `d`.
  double In(double d) const { return absolute ? value : value * d; }
  // In units of d.
  double InD(double d) const { return absolute ? value / d : value; }
};

// "12.5", "12.5d", "5m", "30cm", "5mm" (spaces allowed before the unit). INVALID_ARGUMENT
// naming `field` when `text` is not a finite number with one of these units.
absl::StatusOr<GivenLength> ParseLength(std::string_view text, std::string_view field);

}  // namespace mlsreg
