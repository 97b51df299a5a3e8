#include "server/job_pool.h"

#include <algorithm>
#include <exception>

#include "absl/strings/str_cat.h"
#include "server/log.h"

namespace mlsreg::server {

JobPool::Slot& JobPool::Slot::operator=(Slot&& other) noexcept {
  if (this != &other) {
    if (pool_) pool_->Release(streaming_);
    pool_ = other.pool_;
    streaming_ = other.streaming_;
    other.pool_ = nullptr;
  }
  return *this;
}

JobPool::Slot::~Slot() {
  if (pool_) pool_->Release(streaming_);
}

absl::StatusOr<int> JobPool::Slot::Submit(Run run, Fail fail) {
  if (!pool_) return absl::FailedPreconditionError("job slot already used");
  JobPool& pool = *pool_;
  pool_ = nullptr;
  std::lock_guard<std::mutex> lock(pool.mutex_);
  --pool.reserved_;
  if (streaming_) --pool.reserved_streaming_;
  if (pool.joined_) return absl::UnavailableError("job pool is shutting down");
  const int free_workers = static_cast<int>(pool.threads_.size()) - pool.active_;
  const int ahead = std::max(0, static_cast<int>(pool.queue_.size()) - free_workers);
  pool.queue_.push_back(Job{std::move(run), std::move(fail)});
  pool.wake_.notify_one();
  return ahead;
}

JobPool::JobPool(int workers, int queue_capacity) : capacity_(std::max(0, queue_capacity)) {
  const int n = std::max(1, workers);
  threads_.reserve(n);
  for (int i = 0; i < n; ++i) threads_.emplace_back([this] { WorkerLoop(); });
}

JobPool::~JobPool() { Shutdown(); }

int JobPool::StreamingShare() const {
  return std::max(1, (static_cast<int>(threads_.size()) + capacity_) / 2);
}

absl::StatusOr<JobPool::Slot> JobPool::Reserve(bool streaming) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (stopping_) return absl::UnavailableError("job pool is shutting down");
  // Free workers take the first queued jobs right away, so those do not occupy the queue.
  const int free_workers = static_cast<int>(threads_.size()) - active_;
  const int waiting = static_cast<int>(queue_.size()) + reserved_;
  if (waiting >= free_workers + capacity_) {
    return absl::ResourceExhaustedError(absl::StrCat("job queue full (capacity ", capacity_, ")"));
  }
  if (streaming && reserved_streaming_ >= StreamingShare()) {
    return absl::ResourceExhaustedError(
        absl::StrCat("job queue: ", reserved_streaming_,
                     " places are held by calls still receiving data (at most ", StreamingShare(),
                     "); retry later, or send a small source inline"));
  }
  ++reserved_;
  if (streaming) ++reserved_streaming_;
  return Slot(this, streaming);
}

absl::StatusOr<int> JobPool::TrySubmit(Run run, Fail fail) {
  auto slot = Reserve();
  if (!slot.ok()) return slot.status();
  return slot->Submit(std::move(run), std::move(fail));
}

void JobPool::Release(bool streaming) {
  std::lock_guard<std::mutex> lock(mutex_);
  --reserved_;
  if (streaming) --reserved_streaming_;
}

int JobPool::active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return active_;
}

int JobPool::queued() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(queue_.size()) + reserved_;
}

void JobPool::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
  std::lock_guard<std::mutex> lock(mutex_);
  joined_ = true;
  // Jobs submitted by reserved places after the workers left: they never run, but their
  // callers must hear why.
  while (!queue_.empty()) {
    Job job = std::move(queue_.front());
    queue_.pop_front();
    if (job.fail) job.fail(absl::UnavailableError("server shutting down before the job started"));
  }
}

void JobPool::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping and drained (late submissions: see Shutdown)
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
