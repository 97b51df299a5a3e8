#include "server/registration_job.h"

#include "absl/strings/str_cat.h"

namespace mlsreg::server {

RegistrationJob::RegistrationJob(RegistrationInput input, TargetCache* cache,
                                 const std::atomic<bool>* server_stop)
    : input_(std::move(input)),
      cache_(cache),
      admitted_(std::chrono::steady_clock::now()),
      stop_(server_stop, input_.deadline) {}

absl::Status RegistrationJob::StoppedStatus(int iterations) const {
  return stop_.Status("registration", iterations == 0
                                          ? std::string("before its first iteration")
                                          : absl::StrCat("after ", iterations, " iterations"));
}

void RegistrationJob::SetListener(std::function<void()> on_update) {
  std::lock_guard<std::mutex> lock(mutex_);
  listener_ = std::move(on_update);
}

void RegistrationJob::Notify() {
  std::function<void()> listener;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    listener = listener_;
  }
  changed_.notify_all();
  if (listener) listener();
}

void RegistrationJob::Publish(const IterationReport& report) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    latest_ = report;  // latest wins: an unsent older report is simply replaced
    ++published_;
  }
  Notify();
}

void RegistrationJob::Finish(absl::StatusOr<RegistrationOutcome> outcome) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_) return;  // the first end wins
    outcome_ = std::move(outcome);
    done_ = true;
  }
  Notify();
}

void RegistrationJob::Run() {
  const double queue_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - admitted_).count();
  if (stop_.ShouldStop()) {  // cancelled, timed out or shut down while queued: do not start
    Finish(StoppedStatus(0));
    return;
  }
  // Held until Run returns: the target cannot be evicted under a running registration.
  std::shared_ptr<const Target> target = std::move(input_.target);
  if (!target) {
    auto acquired = cache_->Acquire(input_.target_id, [this] { return stop_.ShouldStop(); });
    if (!acquired.ok()) {
      Finish(acquired.status());
      return;
    }
    target = *std::move(acquired);
  }
  cache_->CountRegistration(input_.target_id);

  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [this](const IterationReport& report) { Publish(report); };
  callbacks.should_stop = [this] { return stop_.ShouldStop(); };
  auto result = mlsreg::Register(*target, input_.source, input_.initial, input_.options, callbacks,
                                 ExecutionOptions{input_.threads});
  if (!result.ok()) {
    Finish(result.status());
    return;
  }
  RegistrationOutcome outcome;
  outcome.queue_seconds = queue_seconds;
  if (input_.ground_truth) {
    outcome.ground_truth_error = EvaluatePose(input_.source.points, result->transform,
                                              *input_.ground_truth, result->sampling_distance);
  }
  outcome.result = *std::move(result);
  outcome.result.trace.clear();  // progress already went out; the wire result has no trace
  Finish(std::move(outcome));
}

RegistrationJob::Update RegistrationJob::WaitForUpdate(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (timeout.count() > 0) {
    changed_.wait_for(lock, timeout, [this] { return done_ || published_ > returned_; });
  }
  Update update;
  if (published_ > returned_) {
    update.progress = latest_;
    returned_ = published_;
  }
  update.done = done_;
  return update;
}

}  // namespace mlsreg::server
