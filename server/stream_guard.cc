#include "server/stream_guard.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "server/retry_hint.h"

namespace mlsreg::server {
namespace {

std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

std::string PeerHost(const std::string& peer) {
  const std::size_t colon = peer.rfind(':');
  const std::size_t scheme = peer.find(':');
  if (colon == std::string::npos || colon == scheme) return peer;  // "unix:/path" etc.
  return peer.substr(0, colon);
}

StreamLimiter::Ticket& StreamLimiter::Ticket::operator=(Ticket&& other) noexcept {
  if (this != &other) {
    if (limiter_) limiter_->Close(host_, client_);
    limiter_ = other.limiter_;
    host_ = std::move(other.host_);
    client_ = std::move(other.client_);
    other.limiter_ = nullptr;
  }
  return *this;
}

StreamLimiter::Ticket::~Ticket() {
  if (limiter_) limiter_->Close(host_, client_);
}

absl::StatusOr<StreamLimiter::Ticket> StreamLimiter::Open(const std::string& peer,
                                                          const std::string& client) {
  std::string host = PeerHost(peer);
  std::lock_guard<std::mutex> lock(mutex_);
  const auto refuse = [](const std::string& why) {
    return RetryLater(absl::ResourceExhaustedError(why), std::chrono::milliseconds(1000));
  };
  if (!client.empty()) {
    if (const auto it = by_client_.find(client);
        it != by_client_.end() && it->second >= max_per_client_) {
      return refuse(absl::StrCat("too many open streams for this client (", client, "; limit ",
                                 max_per_client_,
                                 " per client, max_streams_per_client); finish or cancel some "
                                 "first"));
    }
  }
  if (const auto it = by_host_.find(host); it != by_host_.end() && it->second >= max_per_host_) {
    return refuse(absl::StrCat("too many open streams from ", host, " (limit ", max_per_host_,
                               " per host, max_streams_per_peer); finish or cancel some first"));
  }
  ++by_host_[host];
  if (!client.empty()) ++by_client_[client];
  ++total_;
  return Ticket(this, std::move(host), client);
}

void StreamLimiter::Close(const std::string& host, const std::string& client) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto release = [](std::map<std::string, int>& counts, const std::string& key) {
    const auto it = counts.find(key);
    if (it != counts.end() && --it->second == 0) counts.erase(it);
  };
  release(by_host_, host);
  if (!client.empty()) release(by_client_, client);
  --total_;
}

int StreamLimiter::open_streams() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return total_;
}

void IdleWatched::BeginWait(const char* waiting_for) {
  waiting_for_.store(waiting_for);
  since_ns_.store(NowNs());
}

IdleWatchdog::IdleWatchdog(std::chrono::milliseconds timeout)
    : timeout_(timeout), thread_([this] { Loop(); }) {}

IdleWatchdog::~IdleWatchdog() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void IdleWatchdog::Watch(std::weak_ptr<IdleWatched> call) {
  std::lock_guard<std::mutex> lock(mutex_);
  calls_.push_back(std::move(call));
}

void IdleWatchdog::Loop() {
  // Checked a few times per timeout, so a call ends at most 25 % (or 250 ms) late.
  const auto period =
      std::clamp(timeout_ / 4, std::chrono::milliseconds(10), std::chrono::milliseconds(250));
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, period, [this] { return stopping_; });
    if (stopping_) break;
    std::vector<std::shared_ptr<IdleWatched>> expired;
    const std::int64_t now = NowNs();
    const std::int64_t limit = std::chrono::nanoseconds(timeout_).count();
    std::erase_if(calls_, [&](const std::weak_ptr<IdleWatched>& weak) {
      std::shared_ptr<IdleWatched> call = weak.lock();
      if (!call) return true;
      std::int64_t since = call->since_ns_.load();
      // The exchange makes the timeout fire once, and not if the wait just ended.
      if (since != 0 && now - since > limit && call->since_ns_.compare_exchange_strong(since, 0)) {
        expired.push_back(std::move(call));
      }
      return false;
    });
    lock.unlock();  // calls finish themselves; they may take their own locks
    for (const auto& call : expired) {
      call->OnIdleTimeout(call->waiting_for_.load(), timeout_);
    }
    expired.clear();
    lock.lock();
  }
}

}  // namespace mlsreg::server
