// StopCheck: a caller's "stop now?" question, asked by every loop that can run for long (target
// builds, source preprocessing, feature computation, correspondence search). An empty one never
// stops. Loops ask it through a StopPoller, every few hundred items, so that a cancelled job
// frees its thread within milliseconds while a tight loop pays one counter per item.
#pragma once

#include <cstdint>
#include <functional>

namespace mlsreg {

using StopCheck = std::function<bool()>;

class StopPoller {
 public:
  // Items between two questions; the check is also asked on the first Poll.
  static constexpr std::uint32_t kDefaultInterval = 256;

  explicit StopPoller(const StopCheck& check, std::uint32_t interval = kDefaultInterval)
      : check_(check), interval_(interval == 0 ? 1 : interval) {}

  // Counts one item; true once the check has said stop (and from then on).
  bool Poll() {
    if (stopped_ || !check_) return stopped_;
    if (count_++ % interval_ == 0) stopped_ = check_();
    return stopped_;
  }
  bool stopped() const { return stopped_; }

 private:
  const StopCheck& check_;
  std::uint32_t interval_;
  std::uint32_t count_ = 0;
  bool stopped_ = false;
};

}  // namespace mlsreg
