// JobPool: a fixed set of worker threads fed by a bounded FIFO queue. Registration and target
// builds are CPU work measured in seconds; they run here so gRPC threads only relay, and a full
// queue is refused at once (admission control) instead of piling up.
//
// Admission comes before transfer: a streaming call asks CheckRoom as soon as its header is
// valid, so a request the queue cannot take is refused before its data is sent; it submits once
// its data is complete. (A silent client holds no place.) A job that throws does not take the
// worker down: its `fail` callback gets INTERNAL naming the exception, and the worker goes on.
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
  using Run = std::function<void()>;
  // Told why a job could not finish (it threw); the job's own result is never set then.
  using Fail = std::function<void(absl::Status)>;

  // `workers` >= 1 threads; at most `queue_capacity` jobs wait for one.
  JobPool(int workers, int queue_capacity);
  ~JobPool();  // Shutdown()
  JobPool(const JobPool&) = delete;
  JobPool& operator=(const JobPool&) = delete;

  // Queues `job`. Returns the number of queued jobs ahead of it (0: it starts as soon as a
  // worker is free). RESOURCE_EXHAUSTED "job queue full (capacity N)" when the queue is full,
  // UNAVAILABLE after Shutdown began.
  absl::StatusOr<int> TrySubmit(Run run, Fail fail = {});
  // What TrySubmit would answer now, without queueing anything.
  absl::Status CheckRoom() const;

  int workers() const { return static_cast<int>(threads_.size()); }
  int queue_capacity() const { return capacity_; }
  int active() const;  // jobs running now
  int queued() const;  // jobs waiting

  // Refuses new jobs, runs every queued one (jobs see their own cancel flags and finish
  // quickly), then joins the workers. Idempotent.
  void Shutdown();

 private:
  struct Job {
    Run run;
    Fail fail;
  };
  void WorkerLoop();
  absl::Status CheckRoomLocked() const;

  const int capacity_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> queue_;
  int active_ = 0;  // workers running a job; the others take queued jobs without delay
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace mlsreg::server
