// RpcScope: the bookkeeping around one handler invocation. It counts the call as in flight,
// and Finish() records its status code and latency in the stats, writes the access-log line
// ("rpc=Register request_id=... target=... code=OK duration_ms=...") and converts the status
// for gRPC, with its retry hint as trailing metadata (retry_hint.h): handlers work with
// absl::Status and call Finish exactly once, at their return.
#pragma once

#include <chrono>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "grpcpp/support/status.h"

namespace grpc {
class ServerContextBase;
}
#include "server/service_context.h"

namespace mlsreg::server {

class RpcScope {
 public:
  RpcScope(ServiceContext& context, std::string_view rpc, grpc::ServerContextBase* call);
  ~RpcScope();
  RpcScope(const RpcScope&) = delete;
  RpcScope& operator=(const RpcScope&) = delete;

  void set_target_id(std::string_view id) { target_id_ = id; }
  void set_request_id(std::string_view id) { request_id_ = id; }
  // Extra key=value text for the log line (e.g. "iterations=13").
  void add_detail(std::string_view detail);

  grpc::Status Finish(const absl::Status& status);

 private:
  ServiceContext& context_;
  grpc::ServerContextBase* call_;
  std::string rpc_;
  std::string target_id_;
  std::string request_id_;
  std::string details_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace mlsreg::server
