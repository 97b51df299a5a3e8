// PendingResult<T>: a value produced on a worker and awaited by a gRPC thread that keeps
// checking whether its call is still wanted. Shared (shared_ptr) so a waiter that gives up
// leaves the worker a valid place to put the value.
#pragma once

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>

namespace mlsreg::server {

template <typename T>
class PendingResult {
 public:
  void Set(T value) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      value_.emplace(std::move(value));
    }
    ready_.notify_all();
  }

  // The value once set, or nullopt after `timeout`.
  std::optional<T> WaitFor(std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!ready_.wait_for(lock, timeout, [this] { return value_.has_value(); })) {
      return std::nullopt;
    }
    return std::move(value_);
  }

 private:
  std::mutex mutex_;
  std::condition_variable ready_;
  std::optional<T> value_;
};

}  // namespace mlsreg::server
