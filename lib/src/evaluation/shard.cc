#include "mlsreg/evaluation/shard.h"

#include <algorithm>
#include <cstdlib>
#include <map>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace mlsreg {

absl::StatusOr<ShardSpec> ParseShard(std::string_view text_view, std::string_view flag_view) {
  const std::string text(text_view), flag(flag_view);
  const std::vector<std::string> parts = absl::StrSplit(text, '/');
  ShardSpec shard;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &shard.index) ||
      !absl::SimpleAtoi(parts[1], &shard.count)) {
    return absl::InvalidArgumentError(
        absl::StrCat(flag, ": expected i/N (shard i of N, 0 <= i < N), not '", text, "'"));
  }
  if (shard.count < 1 || shard.count > kMaxShards) {
    return absl::InvalidArgumentError(
        absl::StrCat(flag, ": N must be in [1, ", kMaxShards, "], not ", shard.count));
  }
  if (shard.index < 0 || shard.index >= shard.count) {
    return absl::InvalidArgumentError(absl::StrCat(flag, ": i must be in [0, ", shard.count - 1,
                                                   "] for N = ", shard.count, ", not ",
                                                   shard.index));
  }
  return shard;
}

absl::StatusOr<ShardSpec> ShardFromEnvironment(int count, const char* variable) {
  const char* value = std::getenv(variable);
  if (value == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat("--shard-from-env: the environment variable ", variable,
                     " is not set (Kubernetes sets it in the pods of an Indexed Job)"));
  }
  return ParseShard(absl::StrCat(value, "/", count),
                    absl::StrCat("--shard-from-env (", variable, "=", value, ")"));
}

std::vector<std::size_t> ShardProblems(const Manifest& manifest, const ShardSpec& shard) {
  // Targets in order of first appearance, with their problem counts.
  std::map<std::string, std::size_t> target_of_path;
  std::vector<std::size_t> target_of_problem(manifest.problems.size());
  std::vector<std::size_t> problems_of_target;
  for (std::size_t i = 0; i < manifest.problems.size(); ++i) {
    const auto [it, inserted] =
        target_of_path.emplace(manifest.problems[i].target_path, problems_of_target.size());
    if (inserted) problems_of_target.push_back(0);
    target_of_problem[i] = it->second;
    ++problems_of_target[it->second];
  }
  std::vector<std::size_t> order(problems_of_target.size());
  for (std::size_t t = 0; t < order.size(); ++t) order[t] = t;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return problems_of_target[a] > problems_of_target[b];
  });
  std::vector<std::size_t> load(static_cast<std::size_t>(shard.count), 0);
  std::vector<int> shard_of_target(problems_of_target.size());
  for (std::size_t t : order) {
    const std::size_t lightest =
        static_cast<std::size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    shard_of_target[t] = static_cast<int>(lightest);
    load[lightest] += problems_of_target[t];
  }
  std::vector<std::size_t> mine;
  for (std::size_t i = 0; i < manifest.problems.size(); ++i) {
    if (shard_of_target[target_of_problem[i]] == shard.index) mine.push_back(i);
  }
  return mine;
}

}  // namespace mlsreg
