// AlignJob: one AlignScans call between the gRPC handler that admitted it and the worker that
// runs it. Every finished edge is reported (edges are few: at most n(n-1)/2 for n scans), in the
// order they finish; the handler forwards them and the outcome, and cancels the job when the
// client goes away. Knows nothing of gRPC.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/multiview/align_scans.h"
#include "server/job_stop.h"
#include "server/target_cache.h"

namespace mlsreg::server {

// One scan of a validated request: a cached target (pinned at admission when resident, else
// loaded by the worker) or an uploaded cloud (built by the worker).
struct AlignScanInput {
  std::string target_id;  // empty: uploaded
  std::shared_ptr<const Target> target;
  PointCloud cloud;
};

struct AlignInput {
  std::string request_id;
  std::vector<AlignScanInput> scans;
  AlignOptions options;  // options.threads: ServerConfig::job_threads
  std::chrono::system_clock::time_point deadline = std::chrono::system_clock::time_point::max();
};

struct AlignOutcome {
  AlignResult result;
  double queue_seconds = 0.0;  // admitted -> a worker started it
};

// One finished edge, as the handler relays it.
struct AlignEdgeReport {
  AlignEdge edge;  // its registration's trace cut to the last iteration
  int done = 0, total = 0;
  double elapsed_seconds = 0.0;  // since the worker started the job
};

class AlignJob {
 public:
  // `server_stop` is set when the server's drain time is up; it must outlive the job.
  AlignJob(AlignInput input, TargetCache* cache, const std::atomic<bool>* server_stop);

  // On a worker: loads or builds the scans' targets and aligns them (or nothing, if cancelled
  // while queued).
  void Run();
  void Cancel() { stop_.Cancel(); }
  // Ends the job with `status` when it could not run to its end.
  void Fail(absl::Status status) { Finish(std::move(status)); }
  // Called (on the worker, without the job's lock) after every edge and at the end.
  void SetListener(std::function<void()> on_update);

  struct Update {
    std::optional<AlignEdgeReport> edge;  // the oldest edge not returned before
    bool done = false;                    // no edge left and outcome() is final
  };
  Update NextUpdate();

  // Valid once an Update said done.
  const absl::StatusOr<AlignOutcome>& outcome() const { return outcome_; }
  StopCause stop_cause() const { return stop_.cause(); }

 private:
  absl::StatusOr<std::vector<std::shared_ptr<const Target>>> Targets();
  void Publish(AlignEdgeReport report);
  void Finish(absl::StatusOr<AlignOutcome> outcome);
  void Notify();

  AlignInput input_;
  TargetCache* const cache_;
  const std::chrono::steady_clock::time_point admitted_;
  JobStop stop_;

  std::mutex mutex_;
  std::deque<AlignEdgeReport> edges_;  // guarded by mutex_
  int edges_done_ = 0;                 // guarded by mutex_
  bool done_ = false;                  // guarded by mutex_
  absl::StatusOr<AlignOutcome> outcome_ = absl::UnknownError("not finished");
  std::function<void()> listener_;  // guarded by mutex_
};

}  // namespace mlsreg::server
