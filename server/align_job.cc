#include "server/align_job.h"

#include "absl/strings/str_cat.h"

namespace mlsreg::server {
namespace {

// What the wire carries of an edge's trace: its last RMSE.
void KeepLastIteration(RegistrationResult& registration) {
  if (registration.trace.size() > 1) {
    registration.trace.erase(registration.trace.begin(), registration.trace.end() - 1);
  }
}

}  // namespace

AlignJob::AlignJob(AlignInput input, TargetCache* cache, const std::atomic<bool>* server_stop)
    : input_(std::move(input)),
      cache_(cache),
      admitted_(std::chrono::steady_clock::now()),
      stop_(server_stop, input_.deadline) {}

void AlignJob::SetListener(std::function<void()> on_update) {
  std::lock_guard<std::mutex> lock(mutex_);
  listener_ = std::move(on_update);
}

void AlignJob::Notify() {
  std::function<void()> listener;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    listener = listener_;
  }
  if (listener) listener();
}

void AlignJob::Publish(AlignEdgeReport report) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    edges_.push_back(std::move(report));
    ++edges_done_;
  }
  Notify();
}

void AlignJob::Finish(absl::StatusOr<AlignOutcome> outcome) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_) return;  // the first end wins
    outcome_ = std::move(outcome);
    done_ = true;
  }
  Notify();
}

AlignJob::Update AlignJob::NextUpdate() {
  std::lock_guard<std::mutex> lock(mutex_);
  Update update;
  if (!edges_.empty()) {
    update.edge = std::move(edges_.front());
    edges_.pop_front();
  }
  update.done = done_ && edges_.empty() && !update.edge;
  return update;
}

// Every scan as a target: cached ones from the cache (held until the job ends, so they cannot be
// evicted under it), uploaded ones built here with the library's defaults.
absl::StatusOr<std::vector<std::shared_ptr<const Target>>> AlignJob::Targets() {
  std::vector<std::shared_ptr<const Target>> targets;
  const auto should_stop = [this] { return stop_.ShouldStop(); };
  for (std::size_t i = 0; i < input_.scans.size(); ++i) {
    AlignScanInput& scan = input_.scans[i];
    absl::StatusOr<std::shared_ptr<const Target>> target = std::move(scan.target);
    if (!*target && !scan.target_id.empty()) {
      target = cache_->Acquire(scan.target_id, should_stop);
    } else if (!*target) {
      TargetOptions options;
      options.threads = input_.options.threads;
      target = Target::Build(std::move(scan.cloud), options, should_stop);
    }
    if (!target.ok()) {
      if (stop_.cause() != StopCause::kNone) {
        return stop_.Status("alignment", absl::StrCat("while preparing scans[", i, "]"));
      }
      return absl::Status(target.status().code(),
                          absl::StrCat("scans[", i, "]: ", target.status().message()));
    }
    targets.push_back(*std::move(target));
  }
  return targets;
}

void AlignJob::Run() {
  const auto started = std::chrono::steady_clock::now();
  const double queue_seconds = std::chrono::duration<double>(started - admitted_).count();
  if (stop_.ShouldStop()) {  // cancelled, timed out or shut down while queued: do not start
    Finish(stop_.Status("alignment", "before it started"));
    return;
  }
  auto targets = Targets();
  if (!targets.ok()) {
    Finish(targets.status());
    return;
  }
  for (const AlignScanInput& scan : input_.scans) {
    if (!scan.target_id.empty()) cache_->CountRegistration(scan.target_id);
  }
  AlignCallbacks callbacks;
  callbacks.should_stop = [this] { return stop_.ShouldStop(); };
  callbacks.on_edge = [this, started](const AlignEdge& edge, int done, int total) {
    AlignEdgeReport report{
        edge, done, total,
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()};
    KeepLastIteration(report.edge.registration);
    Publish(std::move(report));
  };
  auto result = AlignTargets(*targets, input_.options, callbacks);
  if (!result.ok()) {
    if (stop_.cause() != StopCause::kNone) {
      int done;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done = edges_done_;
      }
      Finish(stop_.Status("alignment", absl::StrCat("after ", done, " edges")));
    } else {
      Finish(result.status());
    }
    return;
  }
  for (AlignEdge& edge : result->edges) KeepLastIteration(edge.registration);
  Finish(AlignOutcome{*std::move(result), queue_seconds});
}

}  // namespace mlsreg::server
