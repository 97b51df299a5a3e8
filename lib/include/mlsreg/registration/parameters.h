// The parameter table: every registration parameter described once (its path in
// RegistrationOptions, CLI flag, wire field, type, range, help and the group of methods that read
// it). ValidateOptions, the CLI flags (cli/registration_flags.cc) and the wire conversion
// (proto/wire/options_codec.cc) all read it, and tests/unit/parameter_table_test.cc checks it
// against the proto descriptor, so a parameter missing from any side fails the suite.
//
// Adding a parameter: a field in options.h, a row in lib/src/registration/parameters.cc, an
// optional field in RegistrationParameters (mlsreg.proto). Nothing else.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <variant>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/enum_names.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/options.h"

namespace mlsreg {

enum class ParameterType { kInt, kUint64, kDouble, kBool, kEnum };

// An int or enum (as its int value) is int64, a seed uint64; std::monostate is "auto" (a length
// the library chooses from the data, for a row with auto_allowed).
using ParameterValue = std::variant<std::monostate, std::int64_t, std::uint64_t, double, bool>;

// The closed or half-open interval a numeric value must lie in.
struct ParameterRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false;  // (min, ...] instead of [min, ...]
  // Above the lower bound (for a length, in any unit: every length's bound is 0).
  bool AboveMin(double v) const { return min_open ? v > min : v >= min; }
};

struct ParameterSpec {
  std::string_view name;        // "mls.radius_d": the path in RegistrationOptions, in messages
  std::string_view flag;        // "mls-radius": the CLI's --mls-radius ("no-x" for a bool: off)
  std::string_view wire_field;  // "mls_radius_d" in mlsreg.v1.RegistrationParameters
  std::string_view help;
  ParameterGroup group;
  ParameterType type;
  ParameterRange range;         // numeric types
  const EnumNames* enum_names;  // kEnum
  bool auto_allowed;            // kDouble held as std::optional: unset means auto
  std::string_view note;        // appended to the range rule, e.g. "(0 disables)"
  ParameterValue (*get)(const RegistrationOptions& options);
  void (*set)(RegistrationOptions& options, const ParameterValue& value);

  // "must be in (0, 100]", "must be >= 3", "must be one of all, normal, none", "... or auto".
  std::string Rule() const;
  // OK when `value` is of this type and in range; else INVALID_ARGUMENT "<field> <rule>".
  absl::Status Check(const ParameterValue& value, std::string_view field) const;
  // Text as the CLI takes it ("5", "true", "seed-until-converged", "auto").
  std::string Format(const ParameterValue& value) const;
  absl::StatusOr<ParameterValue> Parse(std::string_view text, std::string_view field) const;
  // A length in units of d (the target's mean spacing), which may also be given in the clouds'
  // units (RegistrationOptions::absolute_lengths).
  bool IsLength() const { return type == ParameterType::kDouble && name.ends_with("_d"); }
};

// Sets `spec`'s parameter in `options` from text as the CLI and Python take it: a value of its
// type, "auto" where allowed, and for a length also a value with a unit: "5d" (units of d),
// "1m", "30cm", "5mm" (the clouds' coordinates read as metres; kept in absolute_lengths until
// the target is known). INVALID_ARGUMENT naming `field` otherwise.
absl::Status SetParameterFromText(RegistrationOptions& options, const ParameterSpec& spec,
                                  std::string_view text, std::string_view field);

// `options` with every absolute length converted to units of `d` (absolute_lengths then empty).
// INVALID_ARGUMENT naming the parameter, its value in both units and d when the converted value
// is out of its row's range, or when a name is not a length row.
absl::StatusOr<RegistrationOptions> ResolveLengths(const RegistrationOptions& options, double d);

// Every registration parameter, in help order.
std::span<const ParameterSpec> ParameterTable();
// The row with this name, or null.
const ParameterSpec* FindParameter(std::string_view name);

}  // namespace mlsreg
