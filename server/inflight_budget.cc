#include "server/inflight_budget.h"

#include <algorithm>
#include <string>

#include "absl/strings/str_cat.h"
#include "server/retry_hint.h"

namespace mlsreg::server {

absl::Status InFlightBudget::NoRoom(std::uint64_t bytes, std::string_view field) const {
  return RetryLater(absl::ResourceExhaustedError(
      absl::StrCat(std::string(field), ": the server holds ", used_, " of its ", budget_,
                   " in-flight bytes (max_inflight_bytes) and this request needs ", bytes,
                   " more; retry later")));
}

absl::Status InFlightBudget::Check(std::uint64_t bytes, std::string_view field) const {
  if (bytes > budget_) {
    return Permanent(absl::ResourceExhaustedError(
        absl::StrCat(std::string(field), ": the request needs ", bytes,
                     " bytes in flight, more than the server's whole in-flight budget of ", budget_,
                     " bytes (max_inflight_bytes); send a smaller cloud")));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  if (used_ + bytes > budget_) return NoRoom(bytes, field);
  return absl::OkStatus();
}

absl::Status InFlightBudget::Lease::Grow(std::uint64_t bytes, std::string_view field) {
  std::lock_guard<std::mutex> lock(budget_->mutex_);
  if (budget_->used_ + bytes > budget_->budget_) return budget_->NoRoom(bytes, field);
  budget_->used_ += bytes;
  bytes_ += bytes;
  return absl::OkStatus();
}

void InFlightBudget::Lease::Shrink(std::uint64_t bytes) {
  bytes = std::min(bytes, bytes_);
  if (bytes == 0) return;
  std::lock_guard<std::mutex> lock(budget_->mutex_);
  budget_->used_ -= bytes;
  bytes_ -= bytes;
}

std::uint64_t InFlightBudget::used() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return used_;
}

}  // namespace mlsreg::server
