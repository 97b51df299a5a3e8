#include "server/metrics.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "server/stats.h"

namespace mlsreg::server {
namespace {

// A sample value: integers as such, others with enough digits to round-trip.
std::string Number(double v) { return absl::StrFormat("%.17g", v); }

void Family(std::string_view name, std::string_view type, std::string_view help, std::string* out) {
  absl::StrAppend(out, "# HELP ", std::string(name), " ", std::string(help), "\n# TYPE ",
                  std::string(name), " ", std::string(type), "\n");
}

void Sample(std::string_view name, std::string_view labels, double value, std::string* out) {
  absl::StrAppend(out, std::string(name), labels.empty() ? "" : "{", std::string(labels),
                  labels.empty() ? "" : "}", " ", Number(value), "\n");
}

void Gauge(std::string_view name, std::string_view help, double value, std::string* out,
           std::string_view type = "gauge") {
  Family(name, type, help, out);
  Sample(name, "", value, out);
}

// Label values are RPC, method, code and termination names: [A-Za-z_-]; nothing to escape.
std::string Label(std::string_view key, std::string_view value) {
  return absl::StrCat(std::string(key), "=\"", std::string(value), "\"");
}

}  // namespace

void SecondsHistogram::Observe(double seconds) {
  for (std::size_t i = 0; i < kBounds.size(); ++i) {
    if (seconds <= kBounds[i]) {
      ++counts_[i];
      break;
    }
  }
  ++count_;
  sum_ += seconds;
}

void SecondsHistogram::Render(std::string_view name, std::string_view labels,
                              std::string* out) const {
  const std::string prefix = labels.empty() ? "" : absl::StrCat(std::string(labels), ",");
  std::uint64_t cumulative = 0;
  for (std::size_t i = 0; i < kBounds.size(); ++i) {
    cumulative += counts_[i];
    Sample(absl::StrCat(std::string(name), "_bucket"),
           absl::StrCat(prefix, "le=\"", Number(kBounds[i]), "\""), cumulative, out);
  }
  Sample(absl::StrCat(std::string(name), "_bucket"), absl::StrCat(prefix, "le=\"+Inf\""), count_,
         out);
  Sample(absl::StrCat(std::string(name), "_sum"), labels, sum_, out);
  Sample(absl::StrCat(std::string(name), "_count"), labels, count_, out);
}

void ServerMetrics::RecordRequest(std::string_view rpc, absl::StatusCode code, double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++requests_[{std::string(rpc), StatusCodeName(code)}];
  rpc_seconds_[std::string(rpc)].Observe(seconds);
}

void ServerMetrics::RecordRegistration(std::string_view method, std::string_view termination,
                                       double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++registrations_[{std::string(method), std::string(termination)}];
  method_seconds_[std::string(method)].Observe(seconds);
}

std::string ServerMetrics::Render(const MetricsSnapshot& s) const {
  std::string out;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    Family("mlsreg_requests_total", "counter", "RPCs ended, by RPC and status code", &out);
    for (const auto& [key, n] : requests_) {
      Sample("mlsreg_requests_total",
             absl::StrCat(Label("rpc", key.first), ",", Label("code", key.second)),
             static_cast<double>(n), &out);
    }
    Family("mlsreg_request_duration_seconds", "histogram",
           "Wall time of RPCs from arrival to their status, by RPC", &out);
    for (const auto& [rpc, h] : rpc_seconds_) {
      h.Render("mlsreg_request_duration_seconds", Label("rpc", rpc), &out);
    }
    Family("mlsreg_registrations_total", "counter",
           "Registrations run to their end, by method and termination", &out);
    for (const auto& [key, n] : registrations_) {
      Sample("mlsreg_registrations_total",
             absl::StrCat(Label("method", key.first), ",", Label("termination", key.second)),
             static_cast<double>(n), &out);
    }
    Family("mlsreg_registration_duration_seconds", "histogram",
           "Time registrations ran on a worker (queue excluded), by method", &out);
    for (const auto& [method, h] : method_seconds_) {
      h.Render("mlsreg_registration_duration_seconds", Label("method", method), &out);
    }
  }
  Gauge("mlsreg_workers", "Worker threads", s.workers, &out);
  Gauge("mlsreg_active_jobs", "Jobs (registrations, target builds) running", s.active_jobs, &out);
  Gauge("mlsreg_queue_depth", "Jobs waiting for a worker", s.queue_depth, &out);
  Gauge("mlsreg_queue_capacity", "Jobs that may wait (queue_capacity)", s.queue_capacity, &out);
  Gauge("mlsreg_cache_bytes", "Bytes held by cached targets", s.cache_bytes, &out);
  Gauge("mlsreg_cache_budget_bytes", "The target cache's budget (cache_bytes)",
        s.cache_budget_bytes, &out);
  Gauge("mlsreg_cache_entries", "Targets known (resident or stored)", s.cache_entries, &out);
  Gauge("mlsreg_cache_hits_total", "Target lookups that found the target resident", s.cache_hits,
        &out, "counter");
  Gauge("mlsreg_cache_misses_total", "Target lookups that reloaded it from the data directory",
        s.cache_misses, &out, "counter");
  Gauge("mlsreg_cache_evictions_total", "Targets dropped from memory to make room",
        s.cache_evictions, &out, "counter");
  Gauge("mlsreg_target_builds_total", "Targets built (uploads and reloads)", s.target_builds, &out,
        "counter");
  Gauge("mlsreg_target_build_seconds_total", "Wall time spent building targets",
        s.target_build_seconds, &out, "counter");
  Gauge("mlsreg_inflight_bytes", "Request data held outside the cache", s.inflight_bytes, &out);
  Gauge("mlsreg_inflight_budget_bytes", "The in-flight budget (max_inflight_bytes)",
        s.inflight_budget_bytes, &out);
  Gauge("mlsreg_open_streams", "Streaming calls open (uploads and registrations)", s.open_streams,
        &out);
  Gauge("mlsreg_serving", "1 while the server accepts work, 0 while it drains", s.serving ? 1 : 0,
        &out);
  Gauge("mlsreg_uptime_seconds", "Seconds since the server started", s.uptime_seconds, &out);
  return out;
}

}  // namespace mlsreg::server
