#include "cli/connection_flags.h"

#include <cstdlib>

namespace mlsreg::cli {

void ConnectionFlags::AddTo(CLI::App& app, bool server_required) {
  CLI::Option* server = app.add_option("--server", options_.address,
                                       "server HOST:PORT; several comma-separated (replicas: "
                                       "targets are spread by id); or dns:///NAME:PORT");
  if (server_required) server->required();
  app.add_option("--token", options_.token,
                 "bearer token (default: the MLSREG_TOKEN environment variable)");
  app.add_flag("--tls", options_.tls, "connect with TLS");
  app.add_option("--ca-cert", options_.ca_cert, "PEM file of the CA that signed the server")
      ->check(CLI::ExistingFile);
  app.add_option("--client-cert", options_.client_cert, "PEM client certificate (mutual TLS)")
      ->check(CLI::ExistingFile);
  app.add_option("--client-key", options_.client_key, "PEM client key (mutual TLS)")
      ->check(CLI::ExistingFile);
  app.add_option("--deadline", options_.deadline_seconds, "per-call deadline in seconds")
      ->capture_default_str();
  app.add_option("--attempts", options_.max_attempts,
                 "attempts per call on UNAVAILABLE / RESOURCE_EXHAUSTED")
      ->capture_default_str();
}

absl::StatusOr<std::unique_ptr<client::Client>> ConnectionFlags::Connect() const {
  client::ClientOptions options = options_;
  if (options.token.empty()) {
    if (const char* token = std::getenv("MLSREG_TOKEN")) options.token = token;
  }
  if (!options.ca_cert.empty() || !options.client_cert.empty()) options.tls = true;
  return client::Client::Connect(options);
}

}  // namespace mlsreg::cli
