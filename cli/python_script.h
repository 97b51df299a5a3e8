// Runs a Python script embedded in the binary (the pictures: --plot) with python3, so that the
// binary needs nothing but python3 and python3-matplotlib when a picture is asked for.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"

namespace mlsreg::cli {

// Writes `script` and `input` (its data, e.g. JSON) to a temporary directory and runs
// `python3 SCRIPT INPUT args...` (the interpreter: $MLSREG_PYTHON, else /usr/bin/python3, else
// python3 on PATH). FAILED_PRECONDITION naming `what` when python3 or matplotlib
// is missing or the script fails (its stderr is passed through).
absl::Status RunPythonScript(std::string_view what, std::string_view script, std::string_view input,
                             const std::vector<std::string>& args);

}  // namespace mlsreg::cli
