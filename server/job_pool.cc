#include "server/job_pool.h"

#include <algorithm>
#include <exception>

#include "absl/strings/str_cat.h"
#include "server/log.h"

namespace mlsreg::server {

JobPool::JobPool(int workers, int queue_capacity) : capacity_(std::max(0, queue_capacity)) {
  const int n = std::max(1, workers);
  threads_.reserve(n);
  for (int i = 0; i < n; ++i) threads_.emplace_back([this] { WorkerLoop(); });
}

JobPool::~JobPool() { Shutdown(); }

absl::Status JobPool::CheckRoomLocked() const {
  if (stopping_) return absl::UnavailableError("job pool is shutting down");
  // Free workers take the first queued jobs right away, so those do not occupy the queue.
  const int free_workers = static_cast<int>(threads_.size()) - active_;
  if (static_cast<int>(queue_.size()) >= free_workers + capacity_) {
    return absl::ResourceExhaustedError(absl::StrCat("job queue full (capacity ", capacity_, ")"));
  }
  return absl::OkStatus();
}

absl::Status JobPool::CheckRoom() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return CheckRoomLocked();
}

absl::StatusOr<int> JobPool::TrySubmit(Run run, Fail fail) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (absl::Status s = CheckRoomLocked(); !s.ok()) return s;
  const int free_workers = static_cast<int>(threads_.size()) - active_;
  const int ahead = std::max(0, static_cast<int>(queue_.size()) - free_workers);
  queue_.push_back(Job{std::move(run), std::move(fail)});
  wake_.notify_one();
  return ahead;
}

int JobPool::active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return active_;
}

int JobPool::queued() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(queue_.size());
}

void JobPool::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void JobPool::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping and drained
    Job job = std::move(queue_.front());
    queue_.pop_front();
    ++active_;
    lock.unlock();
    std::string failure;
    try {
      job.run();
    } catch (const std::exception& e) {
      failure = e.what();
    } catch (...) {
      failure = "unknown exception";
    }
    if (!failure.empty()) {
      LogLine(absl::StrCat("worker: job failed with an exception: ", failure));
      if (job.fail) {
        job.fail(absl::InternalError(absl::StrCat("the job failed on the server (", failure,
                                                  "); the server keeps serving")));
      }
    }
    job = Job{};  // release captured state (e.g. a target) before reporting idle
    lock.lock();
    --active_;
  }
}

}  // namespace mlsreg::server
