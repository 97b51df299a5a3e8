#include "server/inflight_budget.h"

#include <string>

#include "absl/strings/str_cat.h"
#include "server/retry_hint.h"

namespace mlsreg::server {

InFlightBudget::Lease& InFlightBudget::Lease::operator=(Lease&& other) noexcept {
  if (this != &other) {
    Release();
    budget_ = other.budget_;
    bytes_ = other.bytes_;
    other.budget_ = nullptr;
  }
  return *this;
}

void InFlightBudget::Lease::Release() {
  if (!budget_) return;
  std::lock_guard<std::mutex> lock(budget_->mutex_);
  budget_->used_ -= bytes_;
  budget_ = nullptr;
}

absl::StatusOr<InFlightBudget::Lease> InFlightBudget::TryAcquire(std::uint64_t bytes,
                                                                 std::string_view field) {
  if (bytes > budget_) {
    return Permanent(absl::ResourceExhaustedError(
        absl::StrCat(std::string(field), ": the request needs ", bytes,
                     " bytes in flight, more than the server's whole in-flight budget of ", budget_,
                     " bytes (max_inflight_bytes); send a smaller cloud")));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  if (used_ + bytes > budget_) {
    return RetryLater(absl::ResourceExhaustedError(
        absl::StrCat(std::string(field), ": the server holds ", used_, " of its ", budget_,
                     " in-flight bytes and this request needs ", bytes, "; retry later")));
  }
  used_ += bytes;
  return Lease(this, bytes);
}

std::uint64_t InFlightBudget::used() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return used_;
}

}  // namespace mlsreg::server
