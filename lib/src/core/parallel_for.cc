#include "mlsreg/core/parallel_for.h"

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <vector>

namespace mlsreg::internal {
namespace {

// One RunOnPool call: its tasks are claimed by index, by the caller and by any worker.
struct Batch {
  Batch(std::size_t count, const std::function<void(std::size_t)>& task)
      : count(count), task(task) {}
  const std::size_t count;
  const std::function<void(std::size_t)>& task;
  std::atomic<std::size_t> next{0};  // the next unclaimed index
  std::atomic<std::size_t> done{0};  // tasks finished
  std::mutex mutex;                  // guards the wake-up of the caller
  std::condition_variable finished;

  // Runs unclaimed tasks until none is left.
  void RunUnclaimed() {
    for (std::size_t k = next.fetch_add(1); k < count; k = next.fetch_add(1)) {
      task(k);
      if (done.fetch_add(1) + 1 == count) {
        const std::lock_guard<std::mutex> lock(mutex);
        finished.notify_all();
      }
    }
  }
  bool Exhausted() const { return next.load() >= count; }
};

class Pool {
 public:
  explicit Pool(int workers) {
    for (int i = 0; i < workers; ++i) workers_.emplace_back([this] { Work(); });
  }

  void Run(std::size_t count, const std::function<void(std::size_t)>& task) {
    const auto batch = std::make_shared<Batch>(count, task);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_back(batch);
    }
    wake_.notify_all();
    batch->RunUnclaimed();
    {
      std::unique_lock<std::mutex> lock(batch->mutex);
      batch->finished.wait(lock, [&] { return batch->done.load() == count; });
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    std::erase(queue_, batch);
  }

 private:
  // A worker: takes the oldest batch with unclaimed tasks and helps with it.
  void Work() {
    for (;;) {
      std::shared_ptr<Batch> batch;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] {
          std::erase_if(queue_, [](const std::shared_ptr<Batch>& b) { return b->Exhausted(); });
          return !queue_.empty();
        });
        batch = queue_.front();
      }
      batch->RunUnclaimed();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::shared_ptr<Batch>> queue_;  // batches that may have unclaimed tasks
  std::vector<std::thread> workers_;
};

}  // namespace

void RunOnPool(std::size_t count, const std::function<void(std::size_t)>& task) {
  // Started on first use and never stopped: its workers sleep between loops, and the process's
  // exit ends them.
  static Pool* const pool = new Pool(std::max(1, HardwareThreads() - 1));
  pool->Run(count, task);
}

}  // namespace mlsreg::internal
