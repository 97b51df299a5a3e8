// The exit codes of every mlsreg command, in one table (printed by `mlsreg manual` into
// docs/cli.md).
#pragma once

#include <cstdio>
#include <span>
#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace mlsreg::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;       // I/O, server, internal error; a failed batch job
inline constexpr int kExitBadInput = 2;     // bad arguments or input (INVALID_ARGUMENT)
inline constexpr int kExitMissed = 3;       // eval: some run failed or missed 5 d
inline constexpr int kExitNotVerified = 4;  // register, verify, align: the result does not verify

// Prints "mlsreg COMMAND: MESSAGE" to stderr and returns the exit code of `status`: bad input
// (INVALID_ARGUMENT) 2, anything else 1.
inline int ExitFor(std::string_view command, const absl::Status& status) {
  std::fprintf(stderr, "mlsreg %s: %s\n", std::string(command).c_str(),
               std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitBadInput : kExitFailed;
}

struct ExitCode {
  int code;
  std::string_view commands;
  std::string_view meaning;
};

inline constexpr ExitCode kExitCodes[] = {
    {kExitOk, "all", "done (health: every server is serving)"},
    {kExitFailed, "all",
     "failed: a file could not be read or written, the server refused or is unreachable, an "
     "internal error (batch: some job failed; health: some server is not serving)"},
    {kExitBadInput, "all", "bad arguments or input (the message names the flag or field)"},
    {kExitMissed, "eval", "some run failed or missed the 5 d success threshold"},
    {kExitNotVerified, "register, verify, align, batch",
     "the registration ran, but its result does not verify against the target (verify: the "
     "given transform does not; align: some scan is joined to the anchor by no verified edge, "
     "and the message names it; batch: every job ran, and some result did not verify: its row "
     "says verified 0 and the verdict): the printed transform must not be trusted"},
};

}  // namespace mlsreg::cli
