// Defences against clients that open streams and then go quiet. Streaming calls (uploads and
// registrations) run on gRPC's callback API, so a quiet client holds no thread, only its call's
// memory; these bound that too, fairly:
//  - per connection: HTTP/2's SETTINGS_MAX_CONCURRENT_STREAMS (max_streams_per_connection, set
//    on the server builder): a client's further calls on that connection wait in the client
//    until one of its streams ends; nobody else's connection is affected;
//  - StreamLimiter: at most N streaming calls open per authenticated client (per bearer token:
//    one token per client), and a ceiling per peer host (the address without its port) above
//    that, for clients without a token of their own; the next one is RESOURCE_EXHAUSTED (retry
//    later) at once.
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

class StreamLimiter {
 public:
  StreamLimiter(int max_per_client, int max_per_host)
      : max_per_client_(max_per_client), max_per_host_(max_per_host) {}

  // A stream's place in the counts; given back when destroyed (or replaced).
  class Ticket {
   public:
    Ticket() = default;
    Ticket(Ticket&& other) noexcept
        : limiter_(other.limiter_),
          host_(std::move(other.host_)),
          client_(std::move(other.client_)) {
      other.limiter_ = nullptr;
    }
    Ticket& operator=(Ticket&& other) noexcept;
    Ticket(const Ticket&) = delete;
    Ticket& operator=(const Ticket&) = delete;
    ~Ticket();

   private:
    friend class StreamLimiter;
    Ticket(StreamLimiter* limiter, std::string host, std::string client)
        : limiter_(limiter), host_(std::move(host)), client_(std::move(client)) {}
    StreamLimiter* limiter_ = nullptr;
    std::string host_, client_;
  };

  // A place for a stream from `peer` ("ipv4:10.0.0.1:5000") called by `client` (who its token
  // says it is, "" without a token). RESOURCE_EXHAUSTED (retry later) when that client already
  // has max_per_client streams open, or its host max_per_host.
  absl::StatusOr<Ticket> Open(const std::string& peer, const std::string& client);
  int open_streams() const;

 private:
  void Close(const std::string& host, const std::string& client);
  const int max_per_client_;
  const int max_per_host_;
  mutable std::mutex mutex_;
  std::map<std::string, int> by_host_, by_client_;
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
