// `mlsreg serve`: runs the gRPC server until SIGTERM/SIGINT, then drains and stops.
// Settings come from an optional JSON config file (--config), overridden field by field by
// flags or MLSREG_* environment variables (handy in containers).
#include <cstdio>
#include <functional>
#include <memory>
#include <vector>

#include "cli/commands.h"
#include "cli/exit_codes.h"
#include "cli/transport.h"
#include "server/server_config.h"

namespace mlsreg::cli {
namespace {

struct ServeArgs {
  std::string config_file;
  server::ServerConfig flags;  // values as parsed from flags/environment
  // Applies the options that were given on top of a config loaded from file.
  std::vector<std::pair<CLI::Option*, std::function<void(server::ServerConfig&)>>> overrides;
};

template <typename T>
void Bind(CLI::App& cmd, ServeArgs& args, const std::string& flag, const std::string& env,
          T server::ServerConfig::*field, const std::string& help) {
  CLI::Option* option = cmd.add_option(flag, args.flags.*field, help)->envname(env);
  option->capture_default_str();
  args.overrides.emplace_back(
      option, [&args, field](server::ServerConfig& c) { c.*field = args.flags.*field; });
}

int RunServe(ServeArgs& args) {
  absl::StatusOr<const TransportApi*> transport = Transport();
  if (!transport.ok()) return ExitFor("serve", transport.status());
  const TransportApi& api = **transport;
  server::ServerConfig config;
  if (!args.config_file.empty()) {
    if (absl::Status s = api.load_server_config(args.config_file, &config); !s.ok()) {
      std::fprintf(stderr, "mlsreg serve: %s\n", std::string(s.message()).c_str());
      return 2;
    }
  }
  for (auto& [option, apply] : args.overrides) {
    if (option->count() > 0 || args.config_file.empty()) apply(config);
  }
  if (absl::Status s = api.validate_server_config(config); !s.ok()) {
    std::fprintf(stderr, "mlsreg serve: %s\n", std::string(s.message()).c_str());
    return 2;
  }
  return api.run_server_until_signal(config);
}

}  // namespace

CommandRunner AddServeCommand(CLI::App& app) {
  auto args = std::make_shared<ServeArgs>();
  CLI::App* cmd = app.add_subcommand("serve", "run the registration server (until SIGTERM)");
  cmd->add_option("--config", args->config_file, "JSON config file (keys = the flag names with _)")
      ->envname("MLSREG_CONFIG");
  using C = server::ServerConfig;
  Bind(*cmd, *args, "--listen", "MLSREG_LISTEN", &C::listen,
       "HOST:PORT to listen on (port 0: any)");
  Bind(*cmd, *args, "--metrics-listen", "MLSREG_METRICS_LISTEN", &C::metrics_listen,
       "HOST:PORT of the Prometheus /metrics endpoint (plain HTTP, no token; port 0: any)");
  Bind(*cmd, *args, "--workers", "MLSREG_WORKERS", &C::workers, "registration threads (0: cores)");
  Bind(*cmd, *args, "--job-threads", "MLSREG_JOB_THREADS", &C::job_threads,
       "threads inside one registration or target build (workers x job threads <= cores)");
  Bind(*cmd, *args, "--queue-capacity", "MLSREG_QUEUE_CAPACITY", &C::queue_capacity,
       "jobs that may wait for a worker (0: 4 x workers); beyond: RESOURCE_EXHAUSTED");
  Bind(*cmd, *args, "--cache-budget-bytes", "MLSREG_CACHE_BUDGET_BYTES", &C::cache_budget_bytes,
       "memory for cached targets (LRU eviction of idle targets)");
  Bind(*cmd, *args, "--data-dir", "MLSREG_DATA_DIR", &C::data_dir,
       "persist targets here (survive eviction and restarts)");
  Bind(*cmd, *args, "--max-points", "MLSREG_MAX_POINTS", &C::max_points, "points per cloud");
  Bind(*cmd, *args, "--max-message-bytes", "MLSREG_MAX_MESSAGE_BYTES", &C::max_message_bytes,
       "gRPC message size limit");
  Bind(*cmd, *args, "--max-chunk-bytes", "MLSREG_MAX_CHUNK_BYTES", &C::max_chunk_bytes,
       "bytes per upload chunk");
  Bind(*cmd, *args, "--max-concurrent-rpcs", "MLSREG_MAX_CONCURRENT_RPCS", &C::max_concurrent_rpcs,
       "gRPC server threads");
  Bind(*cmd, *args, "--tls-cert", "MLSREG_TLS_CERT", &C::tls_cert, "PEM server certificate");
  Bind(*cmd, *args, "--tls-key", "MLSREG_TLS_KEY", &C::tls_key, "PEM server key");
  Bind(*cmd, *args, "--tls-client-ca", "MLSREG_TLS_CLIENT_CA", &C::tls_client_ca,
       "PEM CA for client certificates (mutual TLS)");
  Bind(*cmd, *args, "--allow-insecure-remote", "MLSREG_ALLOW_INSECURE_REMOTE",
       &C::allow_insecure_remote, "allow plaintext on a non-loopback address");
  Bind(*cmd, *args, "--token", "MLSREG_TOKEN", &C::token, "bearer token required by every RPC");
  Bind(*cmd, *args, "--admin-token", "MLSREG_ADMIN_TOKEN", &C::admin_token,
       "bearer token required by DeleteTarget");
  Bind(*cmd, *args, "--token-file", "MLSREG_TOKEN_FILE", &C::token_file,
       "read the bearer token from this file (keeps it out of ps); one token per line gives "
       "each client its own");
  Bind(*cmd, *args, "--admin-token-file", "MLSREG_ADMIN_TOKEN_FILE", &C::admin_token_file,
       "read the admin token from this file");
  Bind(*cmd, *args, "--max-inflight-bytes", "MLSREG_MAX_INFLIGHT_BYTES", &C::max_inflight_bytes,
       "request data held outside the cache; beyond: RESOURCE_EXHAUSTED");
  Bind(*cmd, *args, "--max-streams-per-connection", "MLSREG_MAX_STREAMS_PER_CONNECTION",
       &C::max_streams_per_connection,
       "HTTP/2 streams (any RPC) one connection may have open; further calls wait in the client");
  Bind(*cmd, *args, "--max-streams-per-client", "MLSREG_MAX_STREAMS_PER_CLIENT",
       &C::max_streams_per_client,
       "open uploads + registrations per bearer token (one token per client in --token-file)");
  Bind(*cmd, *args, "--max-streams-per-peer", "MLSREG_MAX_STREAMS_PER_PEER",
       &C::max_streams_per_peer,
       "open uploads + registrations per client host: a ceiling above the per-client limit");
  Bind(*cmd, *args, "--idle-timeout-seconds", "MLSREG_IDLE_TIMEOUT_SECONDS",
       &C::idle_timeout_seconds, "end a stream whose client is silent this long");
  Bind(*cmd, *args, "--reflection", "MLSREG_REFLECTION", &C::reflection,
       "serve gRPC reflection (off by default: it answers without a token)");
  Bind(*cmd, *args, "--drain-seconds", "MLSREG_DRAIN_SECONDS", &C::drain_seconds,
       "on SIGTERM, time running registrations get before they are cancelled");
  return [args] { return RunServe(*args); };
}

}  // namespace mlsreg::cli
