// Retry hints: whether a refusal can succeed later. RESOURCE_EXHAUSTED means both "the queue is
// full right now" and "this target can never fit the cache"; the hint tells a client which, in
// the trailing metadata `mlsreg-retry-after-ms`: a delay in milliseconds worth waiting before a
// retry, or "-1" for never. RpcScope::Finish attaches it; every RESOURCE_EXHAUSTED without an
// explicit hint is sent as transient (kDefaultRetryAfter).
#pragma once

#include <chrono>
#include <optional>

#include "absl/status/status.h"

namespace mlsreg::server {

inline constexpr char kRetryAfterMetadata[] = "mlsreg-retry-after-ms";
inline constexpr std::chrono::milliseconds kDefaultRetryAfter{200};

// `status` marked as worth retrying after `delay`.
absl::Status RetryLater(absl::Status status, std::chrono::milliseconds delay = kDefaultRetryAfter);
// `status` marked as final: the same request will fail the same way.
absl::Status Permanent(absl::Status status);

// The metadata value for `status`: nullopt when there is nothing to say (success, and codes a
// client does not retry), "-1" for permanent, else the delay in milliseconds.
std::optional<std::string> RetryAfterValue(const absl::Status& status);

}  // namespace mlsreg::server
