// JobPool: a fixed set of worker threads fed by a bounded FIFO queue. Registration and target
// builds are CPU work measured in seconds; they run here so gRPC threads only relay, and a full
// queue is refused at once (admission control) instead of piling up.
//
// Admission comes before transfer: a call reserves its place (Reserve) as soon as its header is
// valid, then receives its data, then hands the job to its Slot. Calls whose data is still to
// stream in may hold at most half of the places, so clients that stall mid-upload cannot keep
// the others (whose data came with the header) out. A job that throws does not take
// the worker down: its `fail` callback gets INTERNAL naming the exception, and the worker goes on.
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

  // A place in the queue held for a job whose input is still arriving. Releases the place when
  // destroyed unused.
  class Slot {
   public:
    Slot(Slot&& other) noexcept : pool_(other.pool_), streaming_(other.streaming_) {
      other.pool_ = nullptr;
    }
    Slot& operator=(Slot&& other) noexcept;
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;
    ~Slot();
    // Queues the job in the reserved place. Returns the number of jobs ahead of it;
    // UNAVAILABLE after Shutdown began.
    absl::StatusOr<int> Submit(Run run, Fail fail = {});

   private:
    friend class JobPool;
    Slot(JobPool* pool, bool streaming) : pool_(pool), streaming_(streaming) {}
    JobPool* pool_;
    bool streaming_;
  };

  // `workers` >= 1 threads; at most `queue_capacity` jobs wait for one (reserved places count).
  JobPool(int workers, int queue_capacity);
  ~JobPool();  // Shutdown()
  JobPool(const JobPool&) = delete;
  JobPool& operator=(const JobPool&) = delete;

  // RESOURCE_EXHAUSTED "job queue full (capacity N)" when every place is taken (or, for
  // `streaming` data, every place streaming calls may hold), UNAVAILABLE after Shutdown began.
  absl::StatusOr<Slot> Reserve(bool streaming = false);
  // Reserve() and Submit() in one.
  absl::StatusOr<int> TrySubmit(Run run, Fail fail = {});

  int workers() const { return static_cast<int>(threads_.size()); }
  int queue_capacity() const { return capacity_; }
  int active() const;  // jobs running now
  int queued() const;  // jobs waiting, and places reserved for jobs still receiving data

  // Refuses new jobs, runs every queued one (jobs see their own cancel flags and finish
  // quickly), then joins the workers. Idempotent. A job submitted through a reserved place after
  // the workers left never runs: its `fail` hears UNAVAILABLE.
  void Shutdown();

 private:
  struct Job {
    Run run;
    Fail fail;
  };
  void WorkerLoop();
  void Release(bool streaming);  // a Slot gave its place back unused
  int StreamingShare() const;    // places streaming calls may hold

  const int capacity_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> queue_;
  int reserved_ = 0;            // places held by Slots
  int reserved_streaming_ = 0;  // of which for calls whose data still streams in
  int active_ = 0;              // workers running a job; the others take queued jobs without delay
  bool stopping_ = false;
  bool joined_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace mlsreg::server
