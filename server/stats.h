// RequestStats: per-RPC request counts by status code and latency percentiles, the data behind
// StatsService.GetStats.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

#include "absl/status/status.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::server {

class RequestStats {
 public:
  // Percentiles cover the most recent `window` calls of each RPC (bounded memory, and they
  // follow the current load rather than the whole uptime); counts and max cover every call.
  explicit RequestStats(std::size_t window = 4096) : window_(window) {}

  void Record(std::string_view rpc, absl::StatusCode code, double seconds);

  // Fills `requests` (sorted by rpc, then code) and `latencies` (sorted by rpc).
  void Fill(v1::GetStatsResponse* out) const;

 private:
  struct Latencies {
    std::uint64_t count = 0;
    double max_ms = 0.0;
    std::deque<double> recent_ms;  // at most window_ entries
  };
  const std::size_t window_;
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, absl::StatusCode>, std::uint64_t> counts_;
  std::map<std::string, Latencies> latencies_;
};

// "OK", "INVALID_ARGUMENT", ...: the gRPC status code names (absl uses the same).
std::string StatusCodeName(absl::StatusCode code);

}  // namespace mlsreg::server
