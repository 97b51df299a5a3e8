#include "server/stats.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace mlsreg::server {
namespace {

// Nearest-rank percentile of sorted values.
double Percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const auto rank = static_cast<std::size_t>(std::ceil(p / 100.0 * sorted.size()));
  return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

}  // namespace

std::string StatusCodeName(absl::StatusCode code) { return absl::StatusCodeToString(code); }

void RequestStats::Record(std::string_view rpc, absl::StatusCode code, double seconds) {
  const double ms = seconds * 1e3;
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_[{std::string(rpc), code}];
  Latencies& l = latencies_[std::string(rpc)];
  ++l.count;
  l.max_ms = std::max(l.max_ms, ms);
  l.recent_ms.push_back(ms);
  if (l.recent_ms.size() > window_) l.recent_ms.pop_front();
}

void RequestStats::Fill(v1::GetStatsResponse* out) const {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [key, count] : counts_) {
    v1::RequestCount* c = out->add_requests();
    c->set_rpc(key.first);
    c->set_code(StatusCodeName(key.second));
    c->set_count(count);
  }
  for (const auto& [rpc, l] : latencies_) {
    std::vector<double> sorted(l.recent_ms.begin(), l.recent_ms.end());
    std::sort(sorted.begin(), sorted.end());
    v1::LatencySummary* s = out->add_latencies();
    s->set_rpc(rpc);
    s->set_count(l.count);
    s->set_p50_ms(Percentile(sorted, 50));
    s->set_p90_ms(Percentile(sorted, 90));
    s->set_p99_ms(Percentile(sorted, 99));
    s->set_max_ms(l.max_ms);
  }
}

}  // namespace mlsreg::server
