// ParallelFor: a loop over [0, n) split into contiguous ranges that run at once, one on the
// calling thread and the others on a process-wide pool of workers (started once, on first use).
// The body of one index must not depend on another's, so that results are the same for any
// thread count (every parallel loop in mlsreg is of that kind).
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <thread>

#include "mlsreg/core/stop_check.h"

namespace mlsreg {

// The number of threads "all cores" means (at least 1).
inline int HardwareThreads() {
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

namespace internal {
// Runs task(k) once for every k in [0, count) on this thread and the pool's workers; returns when
// all have run. Any thread may call it, at once with others and from inside a task (a nested
// loop): a caller runs the tasks of its own call that no worker has taken, so it never waits on
// work that nobody is doing.
void RunOnPool(std::size_t count, const std::function<void(std::size_t)>& task);
}  // namespace internal

// Calls body(begin, end, worker) for `threads` (at most one per `min_per_thread` indices, at
// least 1) contiguous ranges covering [0, n); worker is 0 .. threads-1, each range once.
template <typename Body>
void ParallelFor(std::size_t n, int threads, Body&& body, std::size_t min_per_thread = 64) {
  const std::size_t most = std::max<std::size_t>(1, n / std::max<std::size_t>(1, min_per_thread));
  const std::size_t count = std::min<std::size_t>(std::max(1, threads), most);
  if (count <= 1) {
    body(std::size_t{0}, n, 0);
    return;
  }
  const auto range_begin = [&](std::size_t k) { return n * k / count; };
  internal::RunOnPool(
      count, [&](std::size_t k) { body(range_begin(k), range_begin(k + 1), static_cast<int>(k)); });
}

// ParallelFor over the indices one at a time, each range with its own `Scratch` (made once per
// range: a neighbour buffer, a workspace): body(i, scratch) for every i in [0, n) unless
// `should_stop` says stop. Each range asks it every `poll_interval` indices (StopPoller) and
// ends once any range has been told to stop. Returns false when stopped.
template <typename Scratch, typename Body>
bool ParallelForUntilStopped(std::size_t n, int threads, const StopCheck& should_stop, Body&& body,
                             std::uint32_t poll_interval = StopPoller::kDefaultInterval,
                             std::size_t min_per_thread = 64) {
  std::atomic<bool> stopped{false};
  ParallelFor(
      n, threads,
      [&](std::size_t begin, std::size_t end, int) {
        Scratch scratch{};
        StopPoller stop(should_stop, poll_interval);
        for (std::size_t i = begin; i < end; ++i) {
          if (stopped.load(std::memory_order_relaxed) || stop.Poll()) {
            stopped = true;
            return;
          }
          body(i, scratch);
        }
      },
      min_per_thread);
  return !stopped.load();
}

}  // namespace mlsreg
