#include "server/auth.h"

#include <cctype>

#include "grpcpp/server_context.h"

namespace mlsreg::server {
namespace {

// The token of "Bearer <token>" (scheme case-insensitive, RFC 6750), or nullopt.
std::optional<std::string_view> BearerToken(std::string_view value) {
  constexpr std::string_view kScheme = "bearer ";
  if (value.size() <= kScheme.size()) return std::nullopt;
  for (std::size_t i = 0; i < kScheme.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(value[i])) != kScheme[i]) return std::nullopt;
  }
  value.remove_prefix(kScheme.size());
  while (!value.empty() && value.front() == ' ') value.remove_prefix(1);
  if (value.empty()) return std::nullopt;
  return value;
}

}  // namespace

bool ConstantTimeEquals(std::string_view given, std::string_view secret) {
  volatile unsigned char diff = given.size() != secret.size() ? 1 : 0;
  for (std::size_t i = 0; i < secret.size(); ++i) {
    const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
    diff = diff | (g ^ static_cast<unsigned char>(secret[i]));
  }
  return diff == 0;
}

absl::Status TokenAuthenticator::Check(std::optional<std::string_view> authorization,
                                       Access access) const {
  const bool user_required = !token_.empty();
  const bool admin_required = access == Access::kAdmin && !admin_token_.empty();
  if (!authorization) {
    if (user_required || admin_required) {
      return absl::UnauthenticatedError("missing 'authorization: Bearer <token>' metadata");
    }
    return absl::OkStatus();
  }
  const std::optional<std::string_view> presented = BearerToken(*authorization);
  if (!presented) {
    return absl::UnauthenticatedError(
        "malformed authorization metadata: expected 'Bearer <token>'");
  }
  const bool is_admin = !admin_token_.empty() && ConstantTimeEquals(*presented, admin_token_);
  const bool is_user = !token_.empty() && ConstantTimeEquals(*presented, token_);
  if (!is_admin && !is_user && (user_required || admin_required)) {
    return absl::UnauthenticatedError("invalid bearer token");
  }
  if (admin_required && !is_admin) {
    return absl::PermissionDeniedError("this RPC needs the admin token");
  }
  return absl::OkStatus();
}

absl::Status TokenAuthenticator::Check(const grpc::ServerContextBase& context,
                                       Access access) const {
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  if (it == metadata.end()) return Check(std::nullopt, access);
  return Check(std::string_view(it->second.data(), it->second.size()), access);
}

}  // namespace mlsreg::server
