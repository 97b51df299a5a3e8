// RegistrationJob: one registration between the gRPC handler that admitted it and the worker
// that runs it. The worker publishes each iteration into a latest-wins slot (a slow client sees
// fewer, newer reports instead of making the server buffer them); the handler waits on it,
// forwards reports and the outcome, and cancels the job when the client goes away. Knows
// nothing of gRPC.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/registration/registration.h"
#include "server/job_stop.h"
#include "server/target_cache.h"

namespace mlsreg::server {

// A validated request.
struct RegistrationInput {
  std::string request_id;
  std::string target_id;
  // Pinned at admission when resident (so it cannot be evicted while queued); otherwise the
  // worker reloads it from the store.
  std::shared_ptr<const Target> target;
  PointCloud source;
  Matrix4 initial = Matrix4::Identity();
  std::optional<Matrix4> ground_truth;
  RegistrationOptions options;
  int threads = 1;  // ServerConfig::job_threads
  std::chrono::system_clock::time_point deadline = std::chrono::system_clock::time_point::max();
};

struct RegistrationOutcome {
  RegistrationResult result;
  std::optional<PoseError> ground_truth_error;  // when ground truth was given
  double queue_seconds = 0.0;                   // admitted -> a worker started it
};

class RegistrationJob {
 public:
  // `server_stop` is set when the server's drain time is up; it must outlive the job.
  RegistrationJob(RegistrationInput input, TargetCache* cache,
                  const std::atomic<bool>* server_stop);

  // On a worker: runs the registration (or nothing, if cancelled while queued).
  void Run();

  // The client went away: the job stops at its next iteration, or never starts.
  void Cancel() { stop_.Cancel(); }

  // Called (on the worker, without the job's lock) after every new report and at the end.
  void SetListener(std::function<void()> on_update);
  // Ends the job with `status` when it could not run to its end (the worker caught an
  // exception, or the pool shut down before it started).
  void Fail(absl::Status status) { Finish(std::move(status)); }

  struct Update {
    std::optional<IterationReport> progress;  // newer than the one returned before
    bool done = false;                        // outcome() is final
  };
  // Blocks up to `timeout` (0: not at all) for a newer report or the end.
  Update WaitForUpdate(std::chrono::milliseconds timeout);

  // Valid once an Update said done.
  const absl::StatusOr<RegistrationOutcome>& outcome() const { return outcome_; }
  StopCause stop_cause() const { return stop_.cause(); }
  // The status a stopped registration ends with, by cause (JobStop::Status).
  absl::Status StoppedStatus(int iterations) const;
  const std::string& target_id() const { return input_.target_id; }

 private:
  void Publish(const IterationReport& report);
  void Finish(absl::StatusOr<RegistrationOutcome> outcome);
  void Notify();

  RegistrationInput input_;
  TargetCache* const cache_;
  const std::chrono::steady_clock::time_point admitted_;
  JobStop stop_;

  std::mutex mutex_;
  std::condition_variable changed_;
  std::optional<IterationReport> latest_;  // guarded by mutex_
  // Reports published and handed to the handler, counted (not iteration numbers: method auto's
  // stages number their iterations from 1 again).
  std::uint64_t published_ = 0;
  std::uint64_t returned_ = 0;
  bool done_ = false;
  absl::StatusOr<RegistrationOutcome> outcome_ = absl::UnknownError("not finished");
  std::function<void()> listener_;  // guarded by mutex_
};

}  // namespace mlsreg::server
