// The subcommands of the mlsreg tool. Each registers its flags on `app` and returns the exit code
// holder that main() runs after parsing.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace mlsreg::cli {

using CommandRunner = std::function<int()>;

// `mlsreg register`: one in-process registration, streamed one line per iteration.
CommandRunner AddRegisterCommand(CLI::App& app);
// `mlsreg eval`: methods over a manifest with ground truth, one CSV row per run.
CommandRunner AddEvalCommand(CLI::App& app);

}  // namespace mlsreg::cli
