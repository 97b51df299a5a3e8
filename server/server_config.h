// ServerConfig: everything `mlsreg serve` can be told, with the checks that refuse unsafe or
// inconsistent settings before anything listens.
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace mlsreg::server {

struct ServerConfig {
  // host:port; port 0 picks a free port (MlsregServer::port() tells which).
  std::string listen = "127.0.0.1:50051";
  // host:port of the Prometheus /metrics endpoint (plain HTTP, no token); empty: none.
  std::string metrics_listen;
  int workers = 0;         // registration/build threads; 0 = hardware cores
  int queue_capacity = 0;  // jobs waiting for a worker; 0 = 4 * workers
  // Threads inside one registration or target build (keep workers x job_threads <= cores).
  int job_threads = 1;
  std::uint64_t cache_budget_bytes = std::uint64_t{2} << 30;  // resident targets
  // When set, targets are persisted under data_dir/targets and survive eviction and restarts.
  std::string data_dir;
  std::uint64_t max_points = 20'000'000;  // per cloud (target or source)
  int max_message_bytes = 64 << 20;       // gRPC receive/send limit per message
  int max_chunk_bytes = 4 << 20;          // data bytes per CloudChunk
  int max_concurrent_rpcs = 256;          // gRPC sync-server threads (unary RPCs, health)
  // Request data held outside the cache (uploads being received, sources being registered).
  std::uint64_t max_inflight_bytes = std::uint64_t{1} << 30;
  // Fair admission of streams (uploads, registrations, alignments), from the finest to the
  // coarsest: HTTP/2 streams per connection (every RPC counts; further calls wait in the
  // client), streaming calls per authenticated client (per bearer token: give each client its
  // own token in token_file), and a ceiling per peer host, above those with headroom, for
  // everybody behind one address (a NAT, clients without tokens of their own).
  int max_streams_per_connection = 32;
  int max_streams_per_client = 64;
  int max_streams_per_peer = 128;
  // A streaming call that waits this long for its client (a message, or reading one) is ended.
  double idle_timeout_seconds = 30.0;
  // gRPC server reflection (grpcurl without .proto files). Off by default: it answers without
  // a token.
  bool reflection = false;
  // TLS when tls_cert and tls_key are set; mutual TLS (client certificates verified against
  // tls_client_ca) when tls_client_ca is set too. PEM file paths.
  std::string tls_cert, tls_key, tls_client_ca;
  // Plaintext is refused on a non-loopback address unless this is set (e.g. behind a TLS proxy).
  bool allow_insecure_remote = false;
  // Bearer tokens: `token` is required by every RPC when set; `admin_token` by DeleteTarget.
  // The *_file forms read the token from a file (trailing whitespace dropped), so it does not
  // show in `ps`; a token and its file are exclusive. token_file may hold several tokens, one
  // per line: each is a client of its own for max_streams_per_client.
  std::string token, admin_token;
  std::string token_file, admin_token_file;
  // On shutdown, running registrations get this long to finish before they are cancelled.
  double drain_seconds = 10.0;
};

// Reads a JSON object whose keys are the field names above (all optional). Unknown keys and
// wrongly typed values are InvalidArgument naming the key, so a typo never goes unnoticed.
absl::Status LoadConfigFile(const std::string& path, ServerConfig* config);

// Range and consistency checks; an InvalidArgument names the key and its flag ("listen
// (--listen): ..."). listen and metrics_listen must be HOST:PORT with a port in [0, 65535] (or a
// unix socket for listen). Plaintext on a non-loopback address without
// allow_insecure_remote is FailedPrecondition; a TLS or token file that cannot be read is
// InvalidArgument naming the file.
absl::Status Validate(const ServerConfig& config);

// Reads token_file and admin_token_file into token and admin_token.
absl::Status LoadTokenFiles(ServerConfig* config);

// True when `listen` (host:port) names a loopback host (an IPv4 literal in 127.0.0.0/8, ::1,
// localhost) or a unix socket, i.e. nobody else can reach a plaintext port. Host names other
// than localhost are not loopback, whatever they start with.
bool IsLoopbackAddress(const std::string& listen);

// Reads a whole (PEM) file; InvalidArgument naming `what` and the path when it cannot.
absl::StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& what);

}  // namespace mlsreg::server
