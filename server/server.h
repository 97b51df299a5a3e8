// MlsregServer: the mlsreg gRPC server (TargetService, RegistrationService, StatsService, plus
// grpc.health.v1 and, when configured, server reflection) over one target cache and one worker
// pool.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/inflight_budget.h"
#include "server/job_pool.h"
#include "server/metrics.h"
#include "server/metrics_endpoint.h"
#include "server/server_config.h"
#include "server/service_context.h"
#include "server/serving_state.h"
#include "server/stats.h"
#include "server/stream_guard.h"
#include "server/target_cache.h"

namespace grpc {
class Server;
class Service;
}  // namespace grpc

namespace mlsreg::server {

class MlsregServer {
 public:
  // Validates `config`, opens the data directory, starts the workers and listens. Port 0 in
  // config.listen picks a free port (see port()).
  static absl::StatusOr<std::unique_ptr<MlsregServer>> Start(const ServerConfig& config);
  ~MlsregServer();  // Shutdown()

  int port() const { return port_; }
  std::string address() const;                                   // host:port actually listened on
  const ServerConfig& config() const { return config_; }         // resolved (workers, queue) values
  int open_streams() const { return streams_->open_streams(); }  // uploads + registrations
  std::uint64_t inflight_bytes() const { return inflight_->used(); }
  // The Prometheus exposition served at /metrics (server/metrics.h).
  std::string RenderMetrics() const;
  // host:port of the /metrics endpoint (the port actually bound), or "" when not configured.
  std::string metrics_address() const;

  // Graceful stop: health turns NOT_SERVING for every service, new registrations and uploads
  // are refused (UNAVAILABLE), calls in progress get up to drain_seconds to finish; then running
  // registrations are cancelled (their clients get UNAVAILABLE), the listener closes and the
  // workers exit. Blocks until done; safe to call more than once and from any thread.
  void Shutdown();
  // Blocks until Shutdown() has completed.
  void Wait();

 private:
  explicit MlsregServer(const ServerConfig& config);
  bool Idle() const;  // no handler running, no job running or queued
  void DoShutdown();

  ServerConfig config_;
  std::unique_ptr<TargetCache> cache_;
  std::unique_ptr<JobPool> jobs_;
  RequestStats stats_;
  ServerMetrics metrics_;
  std::unique_ptr<TokenAuthenticator> auth_;
  ServingState state_;
  std::unique_ptr<InFlightBudget> inflight_;
  std::unique_ptr<StreamLimiter> streams_;
  std::unique_ptr<IdleWatchdog> idle_;
  std::unique_ptr<ServiceContext> context_;
  std::vector<std::unique_ptr<grpc::Service>> services_;
  std::unique_ptr<grpc::Server> server_;               // stops before what its handlers use
  std::unique_ptr<MetricsEndpoint> metrics_endpoint_;  // last: stops before what it reads
  int port_ = 0;
  std::once_flag shutdown_once_;
};

// `mlsreg serve`: starts the server, logs "mlsreg server listening on HOST:PORT", waits for
// SIGTERM or SIGINT (blocked in every thread and taken with sigwait here), drains and returns 0;
// returns 1 when the server cannot start (the reason is logged).
int RunServerUntilSignal(const ServerConfig& config);

}  // namespace mlsreg::server
