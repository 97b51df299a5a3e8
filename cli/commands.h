// The subcommands of the mlsreg tool. Each registers its flags on `app` and returns the exit code
// holder that main() runs after parsing.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace mlsreg::cli {

using CommandRunner = std::function<int()>;

// `mlsreg register`: one in-process registration, streamed one line per iteration.
CommandRunner AddRegisterCommand(CLI::App& app);
// `mlsreg verify`: the verdict on a given transform.
CommandRunner AddVerifyCommand(CLI::App& app);
// `mlsreg eval`: methods over a manifest with ground truth, one CSV row per run.
CommandRunner AddEvalCommand(CLI::App& app);
// `mlsreg serve`: the gRPC server, until SIGTERM/SIGINT (then drains).
CommandRunner AddServeCommand(CLI::App& app);
// `mlsreg targets upload|get|list|delete`.
CommandRunner AddTargetsCommand(CLI::App& app);
// `mlsreg health` and `mlsreg stats`.
CommandRunner AddHealthCommand(CLI::App& app);
CommandRunner AddStatsCommand(CLI::App& app);
// `mlsreg batch`: many registrations from a manifest against a server.
CommandRunner AddBatchCommand(CLI::App& app);
// `mlsreg align`: many scans into one frame (pairwise edges + pose graph).
CommandRunner AddAlignCommand(CLI::App& app);
// `mlsreg manual` (the Markdown reference, docs/cli.md) and `mlsreg completion bash`, both
// generated from the commands above.
CommandRunner AddManualCommand(CLI::App& app);
CommandRunner AddCompletionCommand(CLI::App& app);

}  // namespace mlsreg::cli
