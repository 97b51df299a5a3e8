// OnDemand<T>: a value of an immutable, shared object that is built by the first caller who needs
// it, once, and then read by every thread without a lock.
#pragma once

#include <atomic>
#include <mutex>
#include <optional>
#include <utility>

namespace mlsreg {

template <class T>
class OnDemand {
 public:
  OnDemand() = default;
  OnDemand(const OnDemand&) = delete;
  OnDemand& operator=(const OnDemand&) = delete;

  // The value, built by `build()` (returning std::optional<T>) when no caller has built it yet.
  // A build that returns nullopt (cancelled) is not kept: the next caller builds again. Callers
  // that arrive while one builds wait for it.
  template <class Build>
  const T* Get(const Build& build) const {
    if (const T* value = ready_.load(std::memory_order_acquire)) return value;
    std::lock_guard<std::mutex> lock(mutex_);
    if (const T* value = ready_.load(std::memory_order_relaxed)) return value;
    std::optional<T> built = build();
    if (!built) return nullptr;
    value_ = std::move(built);
    ready_.store(&*value_, std::memory_order_release);
    return &*value_;
  }

  // Sets the value before the object is shared (no other thread may read it yet).
  void Set(T value) {
    value_ = std::move(value);
    ready_.store(&*value_, std::memory_order_release);
  }

  // The value when it was built, else null.
  const T* IfBuilt() const { return ready_.load(std::memory_order_acquire); }

 private:
  mutable std::mutex mutex_;
  mutable std::optional<T> value_;
  mutable std::atomic<const T*> ready_{nullptr};
};

}  // namespace mlsreg
