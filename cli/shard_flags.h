// --shard i/N and --shard-from-env N, shared by `eval` and `batch` (evaluation/shard.h).
#pragma once

#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "mlsreg/evaluation/shard.h"

namespace mlsreg::cli {

struct ShardFlags {
  std::string shard;  // "i/N"
  int from_env = 0;   // N; i from JOB_COMPLETION_INDEX

  // `items` names what is dealt: "problems" (eval) or "jobs" (batch).
  void AddTo(CLI::App& cmd, const std::string& items) {
    cmd.add_option("--shard", shard,
                   "run only shard i of N (i/N, 0 <= i < N): whole targets, dealt so that the N "
                   "shards have about as many " +
                       items + " each");
    cmd.add_option("--shard-from-env", from_env,
                   "run shard i of this many, i from $JOB_COMPLETION_INDEX (a Kubernetes Indexed "
                   "Job's pod index)")
        ->check(CLI::Range(1, kMaxShards));
  }
  bool given() const { return !shard.empty() || from_env > 0; }
  // The shard asked for, nullopt when none; INVALID_ARGUMENT naming the flag when malformed or
  // when both flags are given.
  absl::StatusOr<std::optional<ShardSpec>> ToSpec() const {
    if (!shard.empty() && from_env > 0) {
      return absl::InvalidArgumentError("give --shard or --shard-from-env, not both");
    }
    if (!given()) return std::optional<ShardSpec>();
    absl::StatusOr<ShardSpec> spec =
        !shard.empty() ? ParseShard(shard) : ShardFromEnvironment(from_env);
    if (!spec.ok()) return spec.status();
    return std::optional<ShardSpec>(*spec);
  }
};

}  // namespace mlsreg::cli
