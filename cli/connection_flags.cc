#include "cli/connection_flags.h"

#include <cctype>
#include <cstdlib>

#include "cli/transport.h"
#include "mlsreg/io/io.h"

namespace mlsreg::cli {

void ConnectionFlags::AddTo(CLI::App& app, bool server_required) {
  CLI::Option* server = app.add_option("--server", options_.address,
                                       "server HOST:PORT; several comma-separated (replicas: "
                                       "targets are spread by id); or dns:///NAME:PORT");
  if (server_required) server->required();
  app.add_option("--token", options_.token,
                 "bearer token (default: the MLSREG_TOKEN environment variable); shows in ps: "
                 "prefer --token-file");
  app.add_option("--token-file", token_file_, "read the bearer token from this file")
      ->check(CLI::ExistingFile)
      ->envname("MLSREG_TOKEN_FILE");
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
  if (!token_file_.empty()) {
    if (!options.token.empty()) {
      return absl::InvalidArgumentError("give --token or --token-file, not both");
    }
    absl::StatusOr<std::string> text = ReadFileBytes(token_file_);
    if (!text.ok())
      return absl::InvalidArgumentError("--token-file: " + std::string(text.status().message()));
    options.token = *std::move(text);
    while (!options.token.empty() &&
           std::isspace(static_cast<unsigned char>(options.token.back()))) {
      options.token.pop_back();
    }
    if (options.token.empty()) {
      return absl::InvalidArgumentError("--token-file: cannot read a token from '" + token_file_ +
                                        "'");
    }
  }
  if (options.token.empty()) {
    if (const char* token = std::getenv("MLSREG_TOKEN")) options.token = token;
  }
  if (!options.ca_cert.empty() || !options.client_cert.empty()) options.tls = true;
  absl::StatusOr<const TransportApi*> transport = Transport();
  if (!transport.ok()) return transport.status();
  return (*transport)->connect(options);
}

}  // namespace mlsreg::cli
