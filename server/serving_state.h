// ServingState: where the server is in its life (serving, draining, stopping) and how many of
// our handlers are running, shared by the handlers and MlsregServer::Shutdown.
#pragma once

#include <atomic>

namespace mlsreg::server {

class ServingState {
 public:
  // False once draining began: new registrations and uploads are refused with UNAVAILABLE.
  bool accepting() const { return !draining_.load(); }
  void BeginDrain() { draining_.store(true); }

  // Set when the drain time is up: running registrations stop at their next iteration.
  const std::atomic<bool>& stop_flag() const { return stop_; }
  void RequestStop() { stop_.store(true); }

  // Handlers in progress (RpcScope counts them).
  void Enter() { in_flight_.fetch_add(1); }
  void Leave() { in_flight_.fetch_sub(1); }
  int in_flight() const { return in_flight_.load(); }

 private:
  std::atomic<bool> draining_{false};
  std::atomic<bool> stop_{false};
  std::atomic<int> in_flight_{0};
};

}  // namespace mlsreg::server
