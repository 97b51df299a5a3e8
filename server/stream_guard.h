// Defences against clients that open streams and then go quiet. Streaming calls (uploads and
// registrations) run on gRPC's callback API, so a quiet client holds no thread, only its call's
// memory; these two bound that too:
//  - PeerStreamLimiter: at most N streaming calls open per peer host (the address without its
//    port); the next one is RESOURCE_EXHAUSTED (retry later) at once.
//  - IdleWatchdog: a call that has waited on its client (for a message, or for it to read one)
//    longer than the idle timeout is ended with DEADLINE_EXCEEDED naming what it waited for.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/statusor.h"

namespace mlsreg::server {

// "ipv4:127.0.0.1:5000" -> "ipv4:127.0.0.1"; "ipv6:[::1]:5000" -> "ipv6:[::1]".
std::string PeerHost(const std::string& peer);

class PeerStreamLimiter {
 public:
  explicit PeerStreamLimiter(int max_per_peer) : max_per_peer_(max_per_peer) {}

  class Ticket {
   public:
    Ticket() = default;
    Ticket(Ticket&& other) noexcept : limiter_(other.limiter_), host_(std::move(other.host_)) {
      other.limiter_ = nullptr;
    }
    Ticket& operator=(Ticket&& other) noexcept;
    Ticket(const Ticket&) = delete;
    Ticket& operator=(const Ticket&) = delete;
    ~Ticket();

   private:
    friend class PeerStreamLimiter;
    Ticket(PeerStreamLimiter* limiter, std::string host)
        : limiter_(limiter), host_(std::move(host)) {}
    PeerStreamLimiter* limiter_ = nullptr;
    std::string host_;
  };

  // RESOURCE_EXHAUSTED (retry later) when `peer` already has max_per_peer streams open.
  absl::StatusOr<Ticket> Open(const std::string& peer);
  int open_streams() const;

 private:
  void Close(const std::string& host);
  const int max_per_peer_;
  mutable std::mutex mutex_;
  std::map<std::string, int> open_;
  int total_ = 0;
};

// A call the watchdog can end. It marks when it waits on its client.
class IdleWatched {
 public:
  virtual ~IdleWatched() = default;
  // On the watchdog's thread, at most once per wait: the client kept the call waiting too long.
  virtual void OnIdleTimeout(const char* waiting_for, std::chrono::milliseconds idle) = 0;

  void BeginWait(const char* waiting_for);  // `waiting_for` must be a string literal
  void EndWait() { since_ns_.store(0); }

 private:
  friend class IdleWatchdog;
  std::atomic<std::int64_t> since_ns_{0};  // steady clock; 0: not waiting
  std::atomic<const char*> waiting_for_{""};
};

class IdleWatchdog {
 public:
  explicit IdleWatchdog(std::chrono::milliseconds timeout);
  ~IdleWatchdog();
  IdleWatchdog(const IdleWatchdog&) = delete;
  IdleWatchdog& operator=(const IdleWatchdog&) = delete;

  void Watch(std::weak_ptr<IdleWatched> call);
  std::chrono::milliseconds timeout() const { return timeout_; }

 private:
  void Loop();
  const std::chrono::milliseconds timeout_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<std::weak_ptr<IdleWatched>> calls_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace mlsreg::server
