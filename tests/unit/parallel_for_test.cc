#include "mlsreg/core/parallel_for.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

namespace mlsreg {
namespace {

// Four callers at once, each running loops whose ranges run nested loops, more ranges than the
// pool has workers: every index of every loop runs exactly once, with its range's worker index.
TEST(ParallelForTest, EveryIndexRunsOnceFromManyCallersAndNestedLoops) {
  constexpr int kCallers = 4, kLoops = 40;
  constexpr std::size_t kOuter = 1000, kInner = 64;
  std::vector<std::vector<std::atomic<int>>> outer(kCallers);
  std::vector<std::atomic<long>> inner(kCallers);
  for (auto& counts : outer) counts = std::vector<std::atomic<int>>(kOuter);
  std::atomic<int> bad_worker{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < kCallers; ++c) {
    callers.emplace_back([&, c] {
      for (int loop = 0; loop < kLoops; ++loop) {
        ParallelFor(
            kOuter, 3,
            [&](std::size_t begin, std::size_t end, int worker) {
              if (worker < 0 || worker >= 3) ++bad_worker;
              for (std::size_t i = begin; i < end; ++i) ++outer[c][i];
              ParallelFor(
                  kInner, 2,
                  [&](std::size_t b, std::size_t e, int) { inner[c] += static_cast<long>(e - b); },
                  8);
            },
            10);
      }
    });
  }
  for (std::thread& t : callers) t.join();
  EXPECT_EQ(bad_worker.load(), 0);
  for (int c = 0; c < kCallers; ++c) {
    for (std::size_t i = 0; i < kOuter; ++i) ASSERT_EQ(outer[c][i].load(), kLoops) << c << " " << i;
    // Each loop has 3 ranges, each running one nested loop over kInner indices.
    EXPECT_EQ(inner[c].load(), static_cast<long>(kLoops) * 3 * static_cast<long>(kInner));
  }
}

}  // namespace
}  // namespace mlsreg
