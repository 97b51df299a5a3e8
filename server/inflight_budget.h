// InFlightBudget: the bytes of request data the server holds outside the target cache: payloads
// being received, decoded clouds waiting in the queue or being registered. A call leases its
// share as soon as its header says how much it will send, before any data arrives, and holds the
// lease until its data is released (a target enters the cache, a registration ends). A lease that
// does not fit now is RESOURCE_EXHAUSTED with a retry hint; one larger than the whole budget is
// RESOURCE_EXHAUSTED for good.
#pragma once

#include <cstdint>
#include <mutex>
#include <string_view>

#include "absl/status/statusor.h"

namespace mlsreg::server {

class InFlightBudget {
 public:
  explicit InFlightBudget(std::uint64_t budget_bytes) : budget_(budget_bytes) {}
  InFlightBudget(const InFlightBudget&) = delete;
  InFlightBudget& operator=(const InFlightBudget&) = delete;

  class Lease {
   public:
    Lease() = default;
    Lease(Lease&& other) noexcept : budget_(other.budget_), bytes_(other.bytes_) {
      other.budget_ = nullptr;
    }
    Lease& operator=(Lease&& other) noexcept;
    Lease(const Lease&) = delete;
    Lease& operator=(const Lease&) = delete;
    ~Lease() { Release(); }
    void Release();
    std::uint64_t bytes() const { return budget_ ? bytes_ : 0; }

   private:
    friend class InFlightBudget;
    Lease(InFlightBudget* budget, std::uint64_t bytes) : budget_(budget), bytes_(bytes) {}
    InFlightBudget* budget_ = nullptr;
    std::uint64_t bytes_ = 0;
  };

  // `field` names what asks (e.g. "header.source") in the message.
  absl::StatusOr<Lease> TryAcquire(std::uint64_t bytes, std::string_view field);

  std::uint64_t used() const;
  std::uint64_t budget() const { return budget_; }

 private:
  const std::uint64_t budget_;
  mutable std::mutex mutex_;
  std::uint64_t used_ = 0;
};

}  // namespace mlsreg::server
