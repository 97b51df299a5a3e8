#include "server/rpc_scope.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "grpcpp/server_context.h"
#include "mlsreg/wire/convert.h"
#include "server/log.h"
#include "server/retry_hint.h"

namespace mlsreg::server {
namespace {

// Client text in log lines is quoted and cut short, so a hostile message cannot forge lines.
std::string Quoted(std::string_view text) {
  constexpr std::size_t kMax = 300;
  std::string out = "\"";
  for (std::size_t i = 0; i < text.size() && i < kMax; ++i) {
    const char c = text[i];
    if (c == '"' || c == '\\') {
      out.push_back('\\');
      out.push_back(c);
    } else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
      out.push_back('?');
    } else {
      out.push_back(c);
    }
  }
  if (text.size() > kMax) out += "...";
  return out + "\"";
}

}  // namespace

RpcScope::RpcScope(ServiceContext& context, std::string_view rpc, grpc::ServerContextBase* call,
                   Admission admission)
    : context_(context), call_(call), rpc_(rpc), start_(std::chrono::steady_clock::now()) {
  context_.state.Enter();
  if (call_ != nullptr) {
    absl::StatusOr<std::string> client = context_.auth.Authenticate(*call_, admission.access);
    admission_ = client.status();
    if (client.ok()) client_ = *std::move(client);
  }
  if (admission_.ok() && admission.refused_while_draining && !context_.state.accepting()) {
    admission_ = absl::UnavailableError("server is shutting down");
  }
}

grpc::Status RpcScope::Run(const std::function<absl::Status()>& body) {
  return Finish(admission_.ok() ? body() : admission_);
}

RpcScope::~RpcScope() { context_.state.Leave(); }

void RpcScope::add_detail(std::string_view detail) { details_.append(" ").append(detail); }

grpc::Status RpcScope::Finish(const absl::Status& status) {
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  context_.stats.Record(rpc_, status.code(), seconds);
  context_.metrics.RecordRequest(rpc_, status.code(), seconds);
  std::string line = absl::StrCat("rpc=", rpc_);
  if (!request_id_.empty()) absl::StrAppend(&line, " request_id=", request_id_);
  if (!target_id_.empty()) absl::StrAppend(&line, " target=", target_id_);
  absl::StrAppend(&line, " code=", StatusCodeName(status.code()),
                  " duration_ms=", absl::StrFormat("%.1f", seconds * 1e3), details_);
  if (!status.ok()) absl::StrAppend(&line, " message=", Quoted(std::string(status.message())));
  LogLine(line);
  if (std::optional<std::string> retry = RetryAfterValue(status); retry && call_) {
    call_->AddTrailingMetadata(kRetryAfterMetadata, *retry);
  }
  return wire::ToGrpcStatus(status);
}

}  // namespace mlsreg::server
