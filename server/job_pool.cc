#include "server/job_pool.h"

#include <algorithm>

#include "absl/strings/str_cat.h"

namespace mlsreg::server {

JobPool::JobPool(int workers, int queue_capacity) : capacity_(std::max(0, queue_capacity)) {
  const int n = std::max(1, workers);
  threads_.reserve(n);
  for (int i = 0; i < n; ++i) threads_.emplace_back([this] { WorkerLoop(); });
}

JobPool::~JobPool() { Shutdown(); }

absl::StatusOr<int> JobPool::TrySubmit(std::function<void()> job) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_) return absl::UnavailableError("job pool is shutting down");
  // Free workers take the first queued jobs right away, so those do not occupy the queue.
  const int free_workers = static_cast<int>(threads_.size()) - active_;
  const int queued = static_cast<int>(queue_.size());
  if (queued >= free_workers + capacity_) {
    return absl::ResourceExhaustedError(absl::StrCat("job queue full (capacity ", capacity_, ")"));
  }
  queue_.push_back(std::move(job));
  wake_.notify_one();
  return std::max(0, queued - free_workers);
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
    std::function<void()> job = std::move(queue_.front());
    queue_.pop_front();
    ++active_;
    lock.unlock();
    job();
    job = nullptr;  // release captured state (e.g. a target) before reporting idle
    lock.lock();
    --active_;
  }
}

}  // namespace mlsreg::server
