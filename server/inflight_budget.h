// InFlightBudget: the bytes of request data the server holds outside the target cache: payloads
// being received and decoded clouds waiting in the queue or being registered. A call's header is
// checked against it before any data is read (Check: a request larger than the whole budget is
// RESOURCE_EXHAUSTED for good, one that does not fit now is RESOURCE_EXHAUSTED with a retry
// hint). Its lease then grows as the data arrives and is decoded, and is given back when the
// data is released (the target enters the cache, the registration ends). So a client that
// declares a huge cloud and sends nothing holds nothing, and the memory the server may hold for
// requests is bounded whatever clients declare.
#pragma once

#include <cstdint>
#include <mutex>
#include <string_view>

#include "absl/status/status.h"

namespace mlsreg::server {

class InFlightBudget {
 public:
  explicit InFlightBudget(std::uint64_t budget_bytes) : budget_(budget_bytes) {}
  InFlightBudget(const InFlightBudget&) = delete;
  InFlightBudget& operator=(const InFlightBudget&) = delete;

  // Bytes held for one call; empty when made, given back when destroyed.
  class Lease {
   public:
    explicit Lease(InFlightBudget* budget) : budget_(budget) {}
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() { Shrink(bytes_); }
    // Takes `bytes` more; RESOURCE_EXHAUSTED (retry later) naming `field` when they do not fit.
    absl::Status Grow(std::uint64_t bytes, std::string_view field);
    void Shrink(std::uint64_t bytes);
    std::uint64_t bytes() const { return bytes_; }

   private:
    InFlightBudget* budget_;
    std::uint64_t bytes_ = 0;
  };

  // Whether a request of `bytes` in total can be received: for good (no, if larger than the
  // budget) and now. Holds nothing.
  absl::Status Check(std::uint64_t bytes, std::string_view field) const;

  std::uint64_t used() const;
  std::uint64_t budget() const { return budget_; }

 private:
  absl::Status NoRoom(std::uint64_t bytes, std::string_view field) const;  // requires mutex_
  const std::uint64_t budget_;
  mutable std::mutex mutex_;
  std::uint64_t used_ = 0;
};

}  // namespace mlsreg::server
