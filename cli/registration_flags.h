// Command-line flags shared by every command that runs a registration.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "absl/status/statusor.h"
#include "mlsreg/registration/registration.h"

namespace mlsreg::cli {

// Binds --method, --samples, --seed, --max-iterations, --mls-radius, ... to a RegistrationOptions
// whose defaults are the paper's. Call ToOptions() after parsing.
class RegistrationFlags {
 public:
  // `method_flag`: false for commands that take a list of methods themselves.
  void AddTo(CLI::App& app, bool method_flag = true);
  absl::StatusOr<RegistrationOptions> ToOptions() const;

 private:
  RegistrationOptions options_;
  std::string method_ = "mls-sicp";
  std::string metric_ = "point-to-plane";
  std::string far_queries_ = "seed-until-converged";
  std::string coarse_filters_ = "all";
};

}  // namespace mlsreg::cli
