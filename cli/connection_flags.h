// Flags that say how to reach a server: --server, --token or --token-file, TLS files, --deadline.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "mlsreg/client/client.h"

namespace mlsreg::cli {

class ConnectionFlags {
 public:
  // `server_required`: the command cannot run locally.
  void AddTo(CLI::App& app, bool server_required);
  bool has_server() const { return !options_.address.empty(); }
  absl::StatusOr<std::unique_ptr<client::Client>> Connect() const;
  const client::ClientOptions& options() const { return options_; }

 private:
  client::ClientOptions options_ = NoServer();
  std::string token_file_;
  static client::ClientOptions NoServer() {
    client::ClientOptions o;
    o.address.clear();  // local unless --server is given
    return o;
  }
};

}  // namespace mlsreg::cli
