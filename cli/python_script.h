// Runs a Python script embedded in the binary (the pictures: --plot) with python3, so that the
// binary needs nothing but python3 and python3-matplotlib when a picture is asked for.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"

namespace mlsreg::cli {

// What a script needs beyond python3: the module's name and its Debian package.
struct PythonNeeds {
  std::string_view module = "matplotlib";
  std::string_view package = "python3-matplotlib";
};

// Writes `script` and `input` (its data, e.g. JSON) to a temporary directory and runs
// `python3 SCRIPT INPUT args...` (the interpreter: $MLSREG_PYTHON, else /usr/bin/python3, else
// python3 on PATH). The script's stderr is kept, not shown: a failure is one message naming
// `what`. FAILED_PRECONDITION when python3 cannot be run or the script exits 3 (the module it
// needs is missing: how to install it); UNAVAILABLE when it exits 4 (its output cannot be
// written) or fails otherwise, with the last line the script wrote on stderr.
absl::Status RunPythonScript(std::string_view what, std::string_view script, std::string_view input,
                             const std::vector<std::string>& args, const PythonNeeds& needs = {});

}  // namespace mlsreg::cli
