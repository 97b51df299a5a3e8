// The networked half of the mlsreg tool, the gRPC client and server, lives in a module
// (libmlsreg_transport.so, built next to the program) that only the commands which talk to or
// run a server load. A local command (register, verify, eval, align without --server) then
// starts without mapping gRPC, protobuf and the forty libraries they bring: that start-up was
// about 6 ms of every one-shot process (`bench/process_start.py`: 11.2 -> 5.4 ms).
#pragma once

#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/client/client.h"
#include "server/server_config.h"

namespace mlsreg::cli {

// Bumped whenever TransportApi changes: a module of another version is refused.
inline constexpr int kTransportApiVersion = 1;
// The module's one exported symbol: extern "C" const TransportApi* mlsreg_transport_api().
inline constexpr char kTransportEntry[] = "mlsreg_transport_api";
inline constexpr char kTransportFile[] = "libmlsreg_transport.so";

struct TransportApi {
  int version = kTransportApiVersion;
  absl::StatusOr<std::unique_ptr<client::Client>> (*connect)(const client::ClientOptions&);
  absl::Status (*load_server_config)(const std::string& path, server::ServerConfig* config);
  absl::Status (*validate_server_config)(const server::ServerConfig& config);
  // Serves until SIGTERM/SIGINT, then drains; the process's exit code.
  int (*run_server_until_signal)(const server::ServerConfig& config);
};

// The module's API, loaded on first use and kept: from $MLSREG_TRANSPORT when set, else
// kTransportFile in the program's directory, else in ../lib/mlsreg/ beside it.
// FAILED_PRECONDITION, naming the places tried and the loader's reason, when there is none.
absl::StatusOr<const TransportApi*> Transport();

}  // namespace mlsreg::cli
