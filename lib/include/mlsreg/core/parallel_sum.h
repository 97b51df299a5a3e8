// ParallelSum: a sum over [0, n) on several threads whose value is the same, bit for bit, for any
// thread count. Floating-point addition is not associative, so a sum split by thread would change
// with the split. Here the indices are cut into blocks of a fixed size that does not depend on the
// thread count: each block is summed in index order into its own accumulator (the blocks run on
// the threads), and the blocks' accumulators are combined in block order on the calling thread.
// One thread takes exactly the same steps. The normal equations of an ICP step are the typical
// use: each pair's terms are added where they are made, so no per-pair storage is needed.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "mlsreg/core/parallel_for.h"

namespace mlsreg {

// Indices per block: large enough that a block's work dwarfs the cost of combining it, small
// enough that a few thousand samples still split over the threads.
inline constexpr std::size_t kSumBlock = 128;

// Returns the sum: for each block, `Accumulator block{}` then add(i, block) for its indices in
// order; then combine(total, block) for the blocks in order, into `Accumulator total{}`.
// `partials` is the caller's scratch (one accumulator per block; kept to reuse its memory across
// calls). `add` must depend only on i and write nothing shared. A thread takes at least
// `min_per_thread` indices (a loop too short for that runs on fewer threads: waking one costs
// tens of microseconds).
template <typename Accumulator, typename Add, typename Combine>
Accumulator ParallelSum(std::size_t n, int threads, std::vector<Accumulator>& partials, Add&& add,
                        Combine&& combine, std::size_t min_per_thread = kSumBlock) {
  const std::size_t blocks = (n + kSumBlock - 1) / kSumBlock;
  partials.resize(blocks);
  ParallelFor(
      blocks, threads,
      [&](std::size_t first, std::size_t last, int) {
        for (std::size_t b = first; b < last; ++b) {
          Accumulator block{};
          const std::size_t end = std::min(n, (b + 1) * kSumBlock);
          for (std::size_t i = b * kSumBlock; i < end; ++i) add(i, block);
          partials[b] = block;
        }
      },
      std::max<std::size_t>(1, min_per_thread / kSumBlock));
  Accumulator total{};
  for (const Accumulator& block : partials) combine(total, block);
  return total;
}

}  // namespace mlsreg
