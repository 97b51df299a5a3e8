#include "server/metrics_endpoint.h"

#include <civetweb.h>

#include <cstring>
#include <mutex>
#include <string_view>

#include "absl/strings/str_cat.h"

namespace mlsreg::server {

absl::StatusOr<std::unique_ptr<MetricsEndpoint>> MetricsEndpoint::Start(
    const std::string& listen, std::function<std::string()> render) {
  static std::once_flag initialised;
  std::call_once(initialised, [] { mg_init_library(0); });
  // civetweb takes "HOST:PORT" (IPv6 "[::1]:PORT") as it is given.
  std::unique_ptr<MetricsEndpoint> endpoint(new MetricsEndpoint(std::move(render)));
  const char* options[] = {"listening_ports",    listen.c_str(), "num_threads", "2",
                           "request_timeout_ms", "10000",        nullptr};
  mg_callbacks callbacks;
  std::memset(&callbacks, 0, sizeof(callbacks));
  char error_text[256] = "";
  mg_init_data init{&callbacks, endpoint.get(), options};
  mg_error_data error{nullptr, error_text, sizeof(error_text)};
  endpoint->context_ = mg_start2(&init, &error);
  if (endpoint->context_ == nullptr) {
    return absl::UnavailableError(absl::StrCat("metrics_listen: cannot listen on ", listen, ": ",
                                               error_text[0] ? error_text : "unknown error"));
  }
  // One handler for every path: civetweb's own file serving (no document root) must never run.
  mg_set_request_handler(endpoint->context_, "**", &MetricsEndpoint::Serve, endpoint.get());
  mg_server_port ports[4];
  const int n = mg_get_server_ports(endpoint->context_, 4, ports);
  if (n > 0) endpoint->port_ = ports[0].port;
  return endpoint;
}

MetricsEndpoint::~MetricsEndpoint() {
  if (context_ != nullptr) mg_stop(context_);
}

int MetricsEndpoint::Serve(mg_connection* connection, void* self) {
  const mg_request_info* request = mg_get_request_info(connection);
  if (request->local_uri == nullptr || std::string_view(request->local_uri) != "/metrics") {
    static constexpr std::string_view kBody = "not found: the metrics are at /metrics\n";
    mg_printf(connection,
              "HTTP/1.1 404 Not Found\r\nContent-Type: text/plain\r\nContent-Length: %zu\r\n"
              "Connection: close\r\n\r\n",
              kBody.size());
    mg_write(connection, kBody.data(), kBody.size());
    return 404;
  }
  if (std::string_view(request->request_method) != "GET" &&
      std::string_view(request->request_method) != "HEAD") {
    mg_printf(connection,
              "HTTP/1.1 405 Method Not Allowed\r\nAllow: GET, HEAD\r\nContent-Length: 0\r\n"
              "Connection: close\r\n\r\n");
    return 405;
  }
  const std::string body = static_cast<MetricsEndpoint*>(self)->render_();
  mg_printf(connection,
            "HTTP/1.1 200 OK\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\n"
            "Content-Length: %zu\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
            body.size());
  if (std::string_view(request->request_method) == "GET") {
    mg_write(connection, body.data(), body.size());
  }
  return 200;
}

}  // namespace mlsreg::server
