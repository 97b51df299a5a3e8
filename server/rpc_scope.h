// RpcScope: the bookkeeping around one handler invocation, and the one place calls are
// admitted. On construction it checks the caller's token for the RPC's access level and, for
// RPCs that start work, that the server is not draining; Run() refuses a call that was not
// admitted before its body runs. It counts the call as in flight, and Finish() records its status
// code and latency in the stats, writes the access-log line
// ("rpc=Register request_id=... target=... code=OK duration_ms=...") and converts the status
// for gRPC, with its retry hint as trailing metadata (retry_hint.h): handlers work with
// absl::Status and call Finish exactly once, at their return.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "grpcpp/support/status.h"

namespace grpc {
class ServerContextBase;
}
#include "server/service_context.h"

namespace mlsreg::server {

// Who may call an RPC, and whether it is refused while the server drains.
struct Admission {
  Access access = Access::kUser;
  bool refused_while_draining = false;  // uploads and registrations: they start work
};
inline constexpr Admission kReadRpc{Access::kUser, false};
inline constexpr Admission kWorkRpc{Access::kUser, true};
inline constexpr Admission kAdminRpc{Access::kAdmin, false};

class RpcScope {
 public:
  RpcScope(ServiceContext& context, std::string_view rpc, grpc::ServerContextBase* call,
           Admission admission);
  ~RpcScope();
  RpcScope(const RpcScope&) = delete;
  RpcScope& operator=(const RpcScope&) = delete;

  void set_target_id(std::string_view id) { target_id_ = id; }
  void set_request_id(std::string_view id) { request_id_ = id; }
  // Extra key=value text for the log line (e.g. "iterations=13").
  void add_detail(std::string_view detail);

  // OK, or why the call is refused (UNAUTHENTICATED, PERMISSION_DENIED, UNAVAILABLE).
  const absl::Status& admission() const { return admission_; }
  // Who is calling, by the token it presented ("token 2", "admin"; "" without a token).
  const std::string& client() const { return client_; }
  // Finish(admission()) when the call is refused, else Finish(body()).
  grpc::Status Run(const std::function<absl::Status()>& body);
  grpc::Status Finish(const absl::Status& status);

 private:
  ServiceContext& context_;
  grpc::ServerContextBase* call_;
  std::string rpc_;
  std::string target_id_;
  std::string request_id_;
  std::string details_;
  std::string client_;
  std::chrono::steady_clock::time_point start_;
  absl::Status admission_;
};

}  // namespace mlsreg::server
