// JobStop: when a job on a worker must stop, and what its caller is told. A job stops when its
// client goes away (Cancel), its call's deadline passes, or the server's drain time is up; the
// first cause seen is kept. Knows nothing of gRPC.
#pragma once

#include <atomic>
#include <chrono>
#include <string_view>

#include "absl/status/status.h"

namespace mlsreg::server {

// Why a job stopped.
enum class StopCause { kNone, kClientCancelled, kDeadline, kShutdown };

class JobStop {
 public:
  // `server_stop` is set when the server's drain time is up; it must outlive this.
  JobStop(const std::atomic<bool>* server_stop, std::chrono::system_clock::time_point deadline)
      : server_stop_(server_stop), deadline_(deadline) {}

  void Cancel() { cancelled_.store(true); }
  // Whether the job must stop now (a StopCheck); records the cause.
  bool ShouldStop();
  StopCause cause() const { return cause_.load(); }

  // The status a stopped job ends with, by cause: a shutdown is UNAVAILABLE (the client may retry
  // elsewhere), a deadline DEADLINE_EXCEEDED, a client's cancel CANCELLED. `job` names the work
  // ("registration") and `when` the point reached ("after 3 iterations").
  absl::Status Status(std::string_view job, std::string_view when) const;

 private:
  const std::atomic<bool>* const server_stop_;
  const std::chrono::system_clock::time_point deadline_;
  std::atomic<bool> cancelled_{false};
  std::atomic<StopCause> cause_{StopCause::kNone};
};

}  // namespace mlsreg::server
