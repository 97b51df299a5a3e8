// ServiceContext: what every RPC handler works with. Owned by MlsregServer, outlives all calls.
#pragma once

#include <chrono>

#include "server/auth.h"
#include "server/inflight_budget.h"
#include "server/job_pool.h"
#include "server/metrics.h"
#include "server/server_config.h"
#include "server/serving_state.h"
#include "server/stats.h"
#include "server/stream_guard.h"
#include "server/target_cache.h"

namespace mlsreg::server {

struct ServiceContext {
  const ServerConfig& config;  // resolved: workers and queue_capacity are > 0
  TargetCache& cache;
  JobPool& jobs;
  RequestStats& stats;
  ServerMetrics& metrics;
  const TokenAuthenticator& auth;
  ServingState& state;
  InFlightBudget& inflight;
  StreamLimiter& streams;
  IdleWatchdog& idle;
  std::chrono::steady_clock::time_point started;
};

}  // namespace mlsreg::server
