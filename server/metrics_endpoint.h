// MetricsEndpoint: a small HTTP server (civetweb) answering GET /metrics with the Prometheus
// text format; every other path is 404. It runs on its own two threads, apart from gRPC's, and
// takes no token (as Prometheus scrapes): bind it where only the scraper reaches.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"

struct mg_context;
struct mg_connection;

namespace mlsreg::server {

class MetricsEndpoint {
 public:
  // Listens on `listen` ("HOST:PORT", port 0: any free port). UNAVAILABLE with civetweb's
  // reason when it cannot (e.g. the port is taken).
  static absl::StatusOr<std::unique_ptr<MetricsEndpoint>> Start(
      const std::string& listen, std::function<std::string()> render);
  ~MetricsEndpoint();  // stops listening, waits for scrapes in progress
  MetricsEndpoint(const MetricsEndpoint&) = delete;
  MetricsEndpoint& operator=(const MetricsEndpoint&) = delete;

  int port() const { return port_; }

 private:
  explicit MetricsEndpoint(std::function<std::string()> render) : render_(std::move(render)) {}
  static int Serve(mg_connection* connection, void* self);

  std::function<std::string()> render_;
  mg_context* context_ = nullptr;
  int port_ = 0;
};

}  // namespace mlsreg::server
