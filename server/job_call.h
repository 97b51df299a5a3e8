// JobCall: a bidirectional StreamingCall that runs one job on a worker and relays it to its
// client (Register and AlignScans). After the request is read (the derived call's reactions),
// Queue() puts the job on the JobPool; from then on the write completions and the job's
// listener pump: the acceptance first, then every update the job has, then the result or the
// status the call ends with. One write at a time, so a slow reader never makes the server
// buffer; what an update is (latest-wins progress, every edge) is the job's business.
#pragma once

#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/inflight_budget.h"
#include "server/streaming_call.h"

namespace mlsreg::server {

template <class Request, class Response, class Job>
class JobCall : public StreamingCall<grpc::ServerBidiReactor<Request, Response>> {
  using Base = StreamingCall<grpc::ServerBidiReactor<Request, Response>>;

 public:
  void OnWriteDone(bool ok) override {
    this->EndWait();
    {
      std::lock_guard<std::mutex> lock(this->mutex_);
      writing_ = false;
    }
    if (!ok) {
      Abandoned();
      this->FinishWith(this->ClientGone());
      return;
    }
    Pump();
  }

 protected:
  using Base::Base;
  enum class Next { kNothing, kWrite, kResult };

  // Under the call's lock, while the job runs or has ended: its next update into out_ (kWrite),
  // or at its end the result into out_ (kResult) or the status the call ends with (an error);
  // kNothing while there is nothing new.
  virtual absl::StatusOr<Next> NextFromJob(Job& job) = 0;

  void ReadNext(const char* what) {
    this->BeginWait(what);
    this->StartUnlessFinished([this] { this->StartRead(&request_); });
  }

  void Abandoned() override {
    std::lock_guard<std::mutex> lock(this->mutex_);
    if (job_) job_->Cancel();
  }

  // Queues the job (holding `lease` until it ends) and announces it. Errors: no room in the
  // queue.
  absl::Status Queue(std::shared_ptr<Job> job, const std::string& request_id,
                     std::shared_ptr<InFlightBudget::Lease> lease) {
    std::weak_ptr<Base> weak = this->self();
    job->SetListener([weak] {
      if (std::shared_ptr<Base> call = weak.lock()) static_cast<JobCall*>(call.get())->Pump();
    });
    {
      std::lock_guard<std::mutex> lock(this->mutex_);
      job_ = job;
    }
    auto position = this->c_.jobs.TrySubmit([job, lease = std::move(lease)] { job->Run(); },
                                            [job](absl::Status s) { job->Fail(std::move(s)); });
    if (!position.ok()) return position.status();
    {
      std::lock_guard<std::mutex> lock(this->mutex_);
      out_.mutable_accepted()->set_request_id(request_id);
      out_.mutable_accepted()->set_queue_position(*position);
      accepted_pending_ = true;
    }
    Pump();
    return absl::OkStatus();
  }

  Request request_;
  Response out_;  // the message being written (alive until OnWriteDone); guarded by mutex_

 private:
  // Sends what is next, if nothing is being written. Called by reactions and, through the job's
  // listener, by the worker. The write starts under the call's lock, so that it never follows
  // the call's Finish (FinishWith, from a cancel or the watchdog).
  void Pump() {
    absl::Status error;
    {
      std::lock_guard<std::mutex> lock(this->mutex_);
      if (this->finished_ || writing_ || !job_) return;
      absl::StatusOr<Next> next = Next::kWrite;
      if (accepted_pending_) {
        accepted_pending_ = false;
      } else {
        next = NextFromJob(*job_);
      }
      if (!next.ok()) {
        error = next.status();
      } else if (*next == Next::kWrite) {
        writing_ = true;
        this->BeginWait("the client to read a response");
        this->StartWrite(&out_);
      } else if (*next == Next::kResult) {
        this->finished_ = true;
        this->EndWait();
        this->StartWriteAndFinish(&out_, grpc::WriteOptions(),
                                  this->scope_.Finish(absl::OkStatus()));
      }
    }
    if (!error.ok()) this->FinishWith(error);
  }

  // Guarded by mutex_:
  std::shared_ptr<Job> job_;
  bool accepted_pending_ = false;
  bool writing_ = false;
};

}  // namespace mlsreg::server
