// Shards: a deterministic share of a manifest's problems, so that N processes (a Kubernetes
// Indexed Job's pods, say) split one evaluation or batch between them and their results merge
// into exactly what one process would have written.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/io/manifest.h"

namespace mlsreg {

// Shard `index` of `count` (0 <= index < count).
struct ShardSpec {
  int index = 0;
  int count = 1;
};

// The largest shard count accepted.
inline constexpr int kMaxShards = 100'000;

// "i/N", as in --shard 2/8. INVALID_ARGUMENT naming `flag` when malformed or out of range.
absl::StatusOr<ShardSpec> ParseShard(std::string_view text, std::string_view flag = "--shard");

// Shard i of `count`, i read from the environment variable `variable` (Kubernetes sets
// JOB_COMPLETION_INDEX in every pod of an Indexed Job). INVALID_ARGUMENT naming the variable
// when it is unset, not an integer, or not below `count`.
absl::StatusOr<ShardSpec> ShardFromEnvironment(int count,
                                               const char* variable = "JOB_COMPLETION_INDEX");

// The indices of the problems in `shard`, in manifest order. Every problem of one target goes to
// the same shard (its target is then read and built once); targets are dealt, largest first
// (ties in manifest order), to the shard with the fewest problems so far (ties to the lowest
// index). The same manifest and count always give the same shards, and the N shards partition
// the problems.
std::vector<std::size_t> ShardProblems(const Manifest& manifest, const ShardSpec& shard);

}  // namespace mlsreg
