// ParallelFor: a loop over [0, n) split into contiguous ranges that run at once, one on the
// calling thread. The body of one index must not depend on another's, so that results are the
// same for any thread count (every parallel loop in mlsreg is of that kind).
#pragma once

#include <algorithm>
#include <cstddef>
#include <thread>
#include <vector>

namespace mlsreg {

// The number of threads "all cores" means (at least 1).
inline int HardwareThreads() {
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

// Calls body(begin, end, worker) for `threads` (at most one per `min_per_thread` indices, at
// least 1) contiguous ranges covering [0, n); worker is 0 .. threads-1, range 0 on this thread.
template <typename Body>
void ParallelFor(std::size_t n, int threads, Body&& body, std::size_t min_per_thread = 64) {
  const std::size_t most = std::max<std::size_t>(1, n / std::max<std::size_t>(1, min_per_thread));
  const std::size_t count = std::min<std::size_t>(std::max(1, threads), most);
  if (count <= 1) {
    body(std::size_t{0}, n, 0);
    return;
  }
  std::vector<std::thread> helpers;
  helpers.reserve(count - 1);
  const auto range_begin = [&](std::size_t k) { return n * k / count; };
  for (std::size_t k = 1; k < count; ++k) {
    helpers.emplace_back([&, k] { body(range_begin(k), range_begin(k + 1), static_cast<int>(k)); });
  }
  body(std::size_t{0}, range_begin(1), 0);
  for (std::thread& t : helpers) t.join();
}

}  // namespace mlsreg
