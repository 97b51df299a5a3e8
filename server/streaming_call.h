// StreamingCall: what the streaming RPCs (CreateTarget, Register, AlignScans) share on gRPC's
// callback API. Such a call holds no thread while it waits for its client: it is a reactor whose
// reactions run briefly on gRPC's threads, with the CPU work on the JobPool. The base owns
//  - the call's lifetime: a shared_ptr to itself, dropped in OnDone, so workers and the idle
//    watchdog can hold weak references and never touch a freed call;
//  - admission at the start (token, draining, the per-client and per-host stream limits);
//  - finishing exactly once, whoever asks first (a reaction, a worker, the watchdog);
//  - the idle timeout (stream_guard.h) and the status of a call its client abandoned.
#pragma once

#include <memory>
#include <mutex>
#include <string_view>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "grpcpp/grpcpp.h"
#include "server/rpc_scope.h"
#include "server/service_context.h"
#include "server/stream_guard.h"

namespace mlsreg::server {

template <class Reactor>
class StreamingCall : public Reactor, public IdleWatched {
 public:
  // Creates the call, registers it with the idle watchdog and starts it (Derived::Begin).
  // The returned reactor belongs to gRPC until OnDone.
  template <class Derived, class... Args>
  static Derived* Launch(ServiceContext& c, grpc::CallbackServerContext* ctx, Args&&... args) {
    auto call = std::make_shared<Derived>(c, ctx, std::forward<Args>(args)...);
    call->self_ = call;
    c.idle.Watch(call);
    if (absl::Status s = call->Admit(); !s.ok()) {
      call->FinishWith(s);
    } else {
      call->Begin();
    }
    return call.get();
  }

  void OnCancel() override {
    Abandoned();
    FinishWith(ClientGone());
  }

  void OnIdleTimeout(const char* waiting_for, std::chrono::milliseconds idle) override {
    Abandoned();
    FinishWith(absl::DeadlineExceededError(
        absl::StrFormat("idle timeout: waited %.1f s for %s (idle_timeout_seconds)",
                        static_cast<double>(idle.count()) / 1e3, waiting_for)));
  }

  void OnDone() override {
    std::shared_ptr<StreamingCall> last = std::move(self_);  // may free this call: last statement
  }

 protected:
  StreamingCall(ServiceContext& c, grpc::CallbackServerContext* ctx, std::string_view rpc)
      : c_(c), ctx_(ctx), scope_(c, rpc, ctx, kWorkRpc) {}

  // The call's work stops (the client cancelled or went idle): cancel jobs, stop builds.
  virtual void Abandoned() = 0;

  // Ends the call with `status` unless it has ended; `before` (may be empty) runs first, under
  // the call's lock, only when this call ends it (e.g. to fill a unary response). Returns
  // whether it ended the call.
  template <class Before = std::nullptr_t>
  bool FinishWith(const absl::Status& status, Before before = nullptr) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (finished_) return false;
      finished_ = true;
      if constexpr (!std::is_same_v<Before, std::nullptr_t>) before();
      // The stream's place is free once its client can see the status: the client may open
      // the next one at once (gRPC destroys the call itself later).
      ticket_ = {};
      EndWait();
      // Under the lock, so that no read or write starts after it (StartUnlessFinished).
      this->Finish(scope_.Finish(status));
    }
    return true;
  }

  // Starts a read or a write (`start`) unless the call has ended, under the call's lock: nothing
  // may start after Finish, since gRPC frees the call once Finish and the operations started
  // before it are done (a late write's completion would reach a freed reactor). gRPC runs no
  // reaction inline, so holding the lock here cannot deadlock. Returns whether it started.
  template <class Start>
  bool StartUnlessFinished(Start start) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (finished_) return false;
    start();
    return true;
  }

  // This call, for weak references from workers (valid until OnDone).
  std::shared_ptr<StreamingCall> self() const { return self_; }

  bool finished() {
    std::lock_guard<std::mutex> lock(mutex_);
    return finished_;
  }

  // Why the call ended when its client is gone: its deadline passed, or it cancelled.
  absl::Status ClientGone() const {
    if (std::chrono::system_clock::now() >= ctx_->deadline()) {
      return absl::DeadlineExceededError("deadline exceeded; the call's work was cancelled");
    }
    return absl::CancelledError("client cancelled; the call's work was cancelled");
  }

  ServiceContext& c_;
  grpc::CallbackServerContext* const ctx_;
  RpcScope scope_;
  std::mutex mutex_;  // guards finished_ and the derived call's shared state
  bool finished_ = false;

 private:
  absl::Status Admit() {
    if (!scope_.admission().ok()) return scope_.admission();  // token and draining
    auto ticket = c_.streams.Open(ctx_->peer(), scope_.client());
    if (!ticket.ok()) return ticket.status();
    ticket_ = *std::move(ticket);
    return absl::OkStatus();
  }

  StreamLimiter::Ticket ticket_;  // guarded by mutex_ once the call has started
  std::shared_ptr<StreamingCall> self_;
};

}  // namespace mlsreg::server
