// JobPool: a fixed set of worker threads fed by a bounded FIFO queue. Registration and target
// builds are CPU work measured in seconds; they run here so gRPC threads only wait, and a full
// queue is refused at once (admission control) instead of piling up.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace mlsreg::server {

class JobPool {
 public:
  // `workers` >= 1 threads; at most `queue_capacity` jobs wait for one.
  JobPool(int workers, int queue_capacity);
  ~JobPool();  // Shutdown()
  JobPool(const JobPool&) = delete;
  JobPool& operator=(const JobPool&) = delete;

  // Queues `job`. Returns the number of queued jobs ahead of it (0: it starts as soon as a
  // worker is free). RESOURCE_EXHAUSTED "job queue full (capacity N)" when the queue is full,
  // UNAVAILABLE after Shutdown began.
  absl::StatusOr<int> TrySubmit(std::function<void()> job);

  int workers() const { return static_cast<int>(threads_.size()); }
  int queue_capacity() const { return capacity_; }
  int active() const;  // jobs running now
  int queued() const;  // jobs waiting

  // Refuses new jobs, runs every queued one (jobs see their own cancel flags and finish
  // quickly), then joins the workers. Idempotent.
  void Shutdown();

 private:
  void WorkerLoop();

  const int capacity_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> queue_;
  int active_ = 0;  // workers running a job; the others take queued jobs without delay
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace mlsreg::server
