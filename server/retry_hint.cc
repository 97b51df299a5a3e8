#include "server/retry_hint.h"

#include <string>

#include "absl/strings/cord.h"
#include "absl/strings/numbers.h"

namespace mlsreg::server {
namespace {

constexpr char kPayloadUrl[] = "type.mlsreg/retry-after-ms";

absl::Status WithHint(absl::Status status, const std::string& value) {
  status.SetPayload(kPayloadUrl, absl::Cord(value));
  return status;
}

}  // namespace

absl::Status RetryLater(absl::Status status, std::chrono::milliseconds delay) {
  return WithHint(std::move(status), std::to_string(delay.count()));
}

absl::Status Permanent(absl::Status status) { return WithHint(std::move(status), "-1"); }

std::optional<std::string> RetryAfterValue(const absl::Status& status) {
  if (auto hint = status.GetPayload(kPayloadUrl)) {
    return std::string(*hint);
  }
  if (status.code() == absl::StatusCode::kResourceExhausted) {
    return std::to_string(kDefaultRetryAfter.count());
  }
  return std::nullopt;
}

}  // namespace mlsreg::server
