// Command-line flags shared by every command that runs a registration: --method and one flag per
// row of the parameter table (mlsreg/registration/parameters.h), grouped in the help by the
// methods that read them.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/registration/registration.h"

namespace mlsreg::cli {

class RegistrationFlags {
 public:
  RegistrationFlags() = default;
  // A command whose registrations default to another method (align: MLS-SICP edges).
  explicit RegistrationFlags(Method default_method) : method_(MethodName(default_method)) {}
  // `method_flag`: false for commands that take a list of methods themselves.
  void AddTo(CLI::App& app, bool method_flag = true);
  // The options the flags gave (defaults elsewhere), validated; the first bad flag's error.
  absl::StatusOr<RegistrationOptions> ToOptions() const;

 private:
  RegistrationOptions options_;
  std::string method_ = std::string(MethodName(RegistrationOptions().method));
  absl::Status error_;  // the first flag whose value did not parse
};

}  // namespace mlsreg::cli
