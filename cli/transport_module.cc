// libmlsreg_transport.so: the gRPC client and server behind the mlsreg tool's networked
// commands (cli/transport.h), one exported table.
#include "cli/transport.h"
#include "server/server.h"

extern "C" __attribute__((visibility("default"))) const mlsreg::cli::TransportApi*
mlsreg_transport_api() {
  static const mlsreg::cli::TransportApi api{
      mlsreg::cli::kTransportApiVersion,     &mlsreg::client::Client::Connect,
      &mlsreg::server::LoadConfigFile,       &mlsreg::server::Validate,
      &mlsreg::server::RunServerUntilSignal,
  };
  return &api;
}
