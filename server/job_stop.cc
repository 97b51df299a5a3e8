#include "server/job_stop.h"

#include <string>

#include "absl/strings/str_cat.h"

namespace mlsreg::server {

bool JobStop::ShouldStop() {
  StopCause cause = StopCause::kNone;
  if (cancelled_.load()) {
    cause = StopCause::kClientCancelled;
  } else if (server_stop_->load()) {
    cause = StopCause::kShutdown;
  } else if (std::chrono::system_clock::now() >= deadline_) {
    cause = StopCause::kDeadline;
  }
  if (cause == StopCause::kNone) return false;
  cause_.store(cause);
  return true;
}

absl::Status JobStop::Status(std::string_view job, std::string_view when) const {
  const std::string j(job), w(when);
  switch (cause()) {
    case StopCause::kShutdown:
      return absl::UnavailableError(
          absl::StrCat("server shutting down: ", j, " stopped ", w, "; retry on another server"));
    case StopCause::kDeadline:
      return absl::DeadlineExceededError(absl::StrCat("deadline exceeded: ", j, " stopped ", w));
    default:
      return absl::CancelledError(absl::StrCat(j, " cancelled ", w));
  }
}

}  // namespace mlsreg::server
