// ServerMetrics: the server's metrics in the Prometheus text exposition format (version 0.0.4),
// served at /metrics by MetricsEndpoint (metrics_endpoint.h) when `serve --metrics-listen` is
// given. Counters and histograms are recorded here as calls end; gauges (queue, cache, in-flight
// bytes) are read from their owners when scraped. Every family is listed in docs/operations.md.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

#include "absl/status/status.h"

namespace mlsreg::server {

// A cumulative histogram over fixed buckets of seconds (1 ms to 10 min).
class SecondsHistogram {
 public:
  static constexpr std::array<double, 15> kBounds = {
      0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 60.0, 600.0};
  void Observe(double seconds);
  // The _bucket, _sum and _count lines of family `name` for the labels `labels` (`a="x",b="y"`
  // or empty).
  void Render(std::string_view name, std::string_view labels, std::string* out) const;

 private:
  std::array<std::uint64_t, kBounds.size()> counts_{};  // per bucket, not cumulative
  std::uint64_t count_ = 0;
  double sum_ = 0.0;
};

// What the scrape reads from the server's parts at that moment.
struct MetricsSnapshot {
  int workers = 0, active_jobs = 0, queue_depth = 0, queue_capacity = 0;
  std::uint64_t cache_bytes = 0, cache_budget_bytes = 0;
  int cache_entries = 0;
  std::uint64_t cache_hits = 0, cache_misses = 0, cache_evictions = 0;
  std::uint64_t target_builds = 0;
  double target_build_seconds = 0.0;
  std::uint64_t inflight_bytes = 0, inflight_budget_bytes = 0;
  int open_streams = 0;
  bool serving = false;
  double uptime_seconds = 0.0;
};

class ServerMetrics {
 public:
  // A call ended with `code` after `seconds` (every RPC, refused calls included).
  void RecordRequest(std::string_view rpc, absl::StatusCode code, double seconds);
  // A registration ran to `termination` ("converged", ...) in `seconds` (its own time, without
  // the queue).
  void RecordRegistration(std::string_view method, std::string_view termination, double seconds);

  // The whole exposition: this object's counters and histograms plus `snapshot`'s gauges.
  std::string Render(const MetricsSnapshot& snapshot) const;

 private:
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, std::string>, std::uint64_t> requests_;  // (rpc, code)
  std::map<std::string, SecondsHistogram> rpc_seconds_;
  std::map<std::pair<std::string, std::string>, std::uint64_t> registrations_;  // (method, end)
  std::map<std::string, SecondsHistogram> method_seconds_;
};

}  // namespace mlsreg::server
