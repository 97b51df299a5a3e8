#include "server/server.h"

#include <csignal>
#include <cstring>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "grpcpp/ext/proto_server_reflection_plugin.h"
#include "grpcpp/grpcpp.h"
#include "grpcpp/health_check_service_interface.h"
#include "grpcpp/impl/server_builder_option.h"
#include "grpcpp/impl/service_type.h"
#include "grpcpp/resource_quota.h"
#include "grpcpp/security/server_credentials.h"
#include "server/log.h"
#include "server/services.h"

namespace mlsreg::server {
namespace {

using Clock = std::chrono::steady_clock;

// Health-checked service names ("" is the server as a whole).
constexpr const char* kServiceNames[] = {"", "mlsreg.v1.TargetService",
                                         "mlsreg.v1.RegistrationService", "mlsreg.v1.StatsService"};

// After the drain time, cancelled registrations stop within one ICP iteration; this bounds the
// wait for them (and for handlers blocked on a silent client, which gRPC then cancels).
constexpr std::chrono::seconds kStopGrace{2};
constexpr std::chrono::milliseconds kDrainPoll{20};

// Server reflection for one builder, on or off. Linking grpc++_reflection registers its plugin
// with every builder of the process (a static initialiser), so the option removes it and adds it
// back only when asked.
class ReflectionOption final : public grpc::ServerBuilderOption {
 public:
  explicit ReflectionOption(bool enabled) : enabled_(enabled) {}
  void UpdateArguments(grpc::ChannelArguments*) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    const std::string name = grpc::reflection::ProtoServerReflectionPlugin().name();
    std::erase_if(*plugins, [&](const auto& plugin) { return plugin->name() == name; });
    if (enabled_)
      plugins->push_back(std::make_unique<grpc::reflection::ProtoServerReflectionPlugin>());
  }

 private:
  bool enabled_;
};

ServerConfig Resolve(ServerConfig config) {
  LoadTokenFiles(&config).IgnoreError();  // Validate() has read them once already
  if (config.workers == 0) {
    config.workers = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  }
  if (config.queue_capacity == 0) config.queue_capacity = 4 * config.workers;
  return config;
}

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> Credentials(const ServerConfig& c) {
  if (c.tls_cert.empty()) return grpc::InsecureServerCredentials();
  auto cert = ReadTextFile(c.tls_cert, "tls_cert");
  if (!cert.ok()) return cert.status();
  auto key = ReadTextFile(c.tls_key, "tls_key");
  if (!key.ok()) return key.status();
  grpc::SslServerCredentialsOptions options(
      c.tls_client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                              : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  options.pem_key_cert_pairs.push_back({*key, *cert});
  if (!c.tls_client_ca.empty()) {
    auto ca = ReadTextFile(c.tls_client_ca, "tls_client_ca");
    if (!ca.ok()) return ca.status();
    options.pem_root_certs = *ca;
  }
  return grpc::SslServerCredentials(options);
}

// "host:port" of the listen address with the port actually bound.
std::string WithPort(const std::string& listen, int port) {
  if (listen.rfind("unix", 0) == 0) return listen;
  const std::size_t colon = listen.rfind(':');
  const std::string host = colon == std::string::npos ? listen : listen.substr(0, colon);
  return absl::StrCat(host, ":", port);
}

}  // namespace

MlsregServer::MlsregServer(const ServerConfig& config) : config_(Resolve(config)) {}

MlsregServer::~MlsregServer() { Shutdown(); }

std::string MlsregServer::address() const { return WithPort(config_.listen, port_); }

absl::StatusOr<std::unique_ptr<MlsregServer>> MlsregServer::Start(const ServerConfig& config) {
  if (absl::Status s = Validate(config); !s.ok()) return s;
  std::unique_ptr<MlsregServer> server(new MlsregServer(config));
  const ServerConfig& c = server->config_;

  std::unique_ptr<TargetStore> store;
  if (!c.data_dir.empty()) {
    auto opened = TargetStore::Open(c.data_dir);
    if (!opened.ok()) return opened.status();
    store = *std::move(opened);
  }
  auto cache = TargetCache::Open(c.cache_budget_bytes, std::move(store), c.job_threads);
  if (!cache.ok()) return cache.status();
  server->cache_ = *std::move(cache);
  server->jobs_ = std::make_unique<JobPool>(c.workers, c.queue_capacity);
  server->auth_ = std::make_unique<TokenAuthenticator>(c.token, c.admin_token);
  server->inflight_ = std::make_unique<InFlightBudget>(c.max_inflight_bytes);
  server->streams_ =
      std::make_unique<StreamLimiter>(c.max_streams_per_client, c.max_streams_per_peer);
  server->idle_ = std::make_unique<IdleWatchdog>(
      std::chrono::milliseconds(static_cast<std::int64_t>(c.idle_timeout_seconds * 1000.0)));
  server->context_ = std::make_unique<ServiceContext>(ServiceContext{
      c, *server->cache_, *server->jobs_, server->stats_, server->metrics_, *server->auth_,
      server->state_, *server->inflight_, *server->streams_, *server->idle_, Clock::now()});
  server->services_.push_back(NewTargetService(*server->context_));
  server->services_.push_back(NewRegistrationService(*server->context_));
  server->services_.push_back(NewStatsService(*server->context_));

  auto credentials = Credentials(c);
  if (!credentials.ok()) return credentials.status();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder builder;
  builder.SetOption(std::make_unique<ReflectionOption>(c.reflection));
  builder.AddListeningPort(c.listen, *credentials, &server->port_);
  // gRPC sets SO_REUSEPORT by default: a second server on a bound port would start and share
  // its connections with the first. Without it, binding a port in use fails.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // HTTP/2 streams one connection may have open at once: a client's further calls on it wait
  // (in the client) for one to end, and no other connection is affected.
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, c.max_streams_per_connection);
  for (const auto& service : server->services_) builder.RegisterService(service.get());
  builder.SetMaxReceiveMessageSize(c.max_message_bytes);
  builder.SetMaxSendMessageSize(c.max_message_bytes);
  // Unary calls and health checks run on the sync server's threads; this caps them (excess
  // calls get RESOURCE_EXHAUSTED from gRPC). Streaming calls run on the callback API and hold no
  // thread while their client is quiet.
  grpc::ResourceQuota quota("mlsreg");
  quota.SetMaxThreads(c.max_concurrent_rpcs);
  builder.SetResourceQuota(quota);
  server->server_ = builder.BuildAndStart();
  if (!server->server_ || server->port_ == 0) {
    return absl::UnavailableError(
        absl::StrCat("listen: cannot listen on '", c.listen,
                     "': the address is in use (another server?) or cannot be bound here"));
  }
  grpc::HealthCheckServiceInterface* health = server->server_->GetHealthCheckService();
  for (const char* name : kServiceNames) health->SetServingStatus(name, true);
  if (!c.metrics_listen.empty()) {
    auto endpoint = MetricsEndpoint::Start(c.metrics_listen,
                                           [raw = server.get()] { return raw->RenderMetrics(); });
    if (!endpoint.ok()) return endpoint.status();
    server->metrics_endpoint_ = *std::move(endpoint);
  }
  return server;
}

std::string MlsregServer::RenderMetrics() const {
  MetricsSnapshot s;
  s.workers = jobs_->workers();
  s.active_jobs = jobs_->active();
  s.queue_depth = jobs_->queued();
  s.queue_capacity = jobs_->queue_capacity();
  const CacheCounters cache = cache_->counters();
  s.cache_bytes = cache.bytes;
  s.cache_budget_bytes = cache.budget_bytes;
  s.cache_entries = cache.entries;
  s.cache_hits = cache.hits;
  s.cache_misses = cache.misses;
  s.cache_evictions = cache.evictions;
  s.target_builds = cache.builds;
  s.target_build_seconds = cache.build_seconds;
  s.inflight_bytes = inflight_->used();
  s.inflight_budget_bytes = inflight_->budget();
  s.open_streams = streams_->open_streams();
  s.serving = state_.accepting();
  s.uptime_seconds = std::chrono::duration<double>(Clock::now() - context_->started).count();
  return metrics_.Render(s);
}

std::string MlsregServer::metrics_address() const {
  if (!metrics_endpoint_) return "";
  const std::string& listen = config_.metrics_listen;
  return absl::StrCat(listen.substr(0, listen.rfind(':')), ":", metrics_endpoint_->port());
}

bool MlsregServer::Idle() const {
  return state_.in_flight() == 0 && jobs_->active() == 0 && jobs_->queued() == 0;
}

void MlsregServer::Shutdown() {
  std::call_once(shutdown_once_, [this] { DoShutdown(); });
}

void MlsregServer::DoShutdown() {
  if (!server_) {  // Start failed part-way
    if (jobs_) jobs_->Shutdown();
    return;
  }
  // 1. Tell load balancers and refuse new work, but keep answering health checks and calls.
  state_.BeginDrain();
  server_->GetHealthCheckService()->SetServingStatus(false);
  LogLine(absl::StrFormat("draining: %d calls in flight, %d jobs running, %d queued (up to %gs)",
                          state_.in_flight(), jobs_->active(), jobs_->queued(),
                          config_.drain_seconds));
  // 2. Let what is running finish.
  const auto drain_deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(config_.drain_seconds));
  while (!Idle() && Clock::now() < drain_deadline) std::this_thread::sleep_for(kDrainPoll);
  // 3. Time is up: stop registrations at their next iteration.
  if (!Idle()) {
    LogLine(absl::StrFormat("drain time up: cancelling %d running and %d queued jobs",
                            jobs_->active(), jobs_->queued()));
    state_.RequestStop();
    const auto stop_deadline = Clock::now() + kStopGrace;
    while (!Idle() && Clock::now() < stop_deadline) std::this_thread::sleep_for(kDrainPoll);
  }
  // 4. Close the listener; gRPC cancels calls still open after the grace period.
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(1));
  jobs_->Shutdown();
  LogLine("stopped");
}

void MlsregServer::Wait() {
  if (server_) server_->Wait();
}

int RunServerUntilSignal(const ServerConfig& config) {
  // Blocked before any thread starts, so every gRPC and worker thread inherits the mask and
  // the signals are delivered only to sigwait below.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto server = MlsregServer::Start(config);
  if (!server.ok()) {
    LogLine(absl::StrCat("cannot start server: ", server.status().ToString()));
    return 1;
  }
  const ServerConfig& c = (*server)->config();
  if (!(*server)->metrics_address().empty()) {
    LogLine(absl::StrCat("metrics on http://", (*server)->metrics_address(), "/metrics"));
  }
  LogLine(absl::StrFormat(
      "server listening on %s (%s, %d workers, queue %d, cache %d MiB%s%s)", (*server)->address(),
      c.tls_cert.empty() ? "plaintext" : (c.tls_client_ca.empty() ? "TLS" : "mutual TLS"),
      c.workers, c.queue_capacity, c.cache_budget_bytes >> 20,
      c.data_dir.empty() ? "" : ", data dir " + c.data_dir, c.token.empty() ? "" : ", token auth"));
  int received = 0;
  sigwait(&signals, &received);
  LogLine(absl::StrCat("received ", strsignal(received), ": shutting down"));
  (*server)->Shutdown();
  return 0;
}

}  // namespace mlsreg::server
