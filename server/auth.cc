#include "server/auth.h"

#include <cctype>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
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

TokenAuthenticator::TokenAuthenticator(std::string_view tokens, std::string admin_token)
    : admin_token_(std::move(admin_token)) {
  for (absl::string_view line : absl::StrSplit(absl::string_view(tokens.data(), tokens.size()),
                                               '\n', absl::SkipWhitespace())) {
    tokens_.emplace_back(absl::StripAsciiWhitespace(line));
  }
}

absl::StatusOr<std::string> TokenAuthenticator::Authenticate(
    std::optional<std::string_view> authorization, Access access) const {
  const bool user_required = !tokens_.empty();
  const bool admin_required = access == Access::kAdmin && !admin_token_.empty();
  if (!authorization) {
    if (user_required || admin_required) {
      return absl::UnauthenticatedError("missing 'authorization: Bearer <token>' metadata");
    }
    return std::string();
  }
  const std::optional<std::string_view> presented = BearerToken(*authorization);
  if (!presented) {
    return absl::UnauthenticatedError(
        "malformed authorization metadata: expected 'Bearer <token>'");
  }
  const bool is_admin = !admin_token_.empty() && ConstantTimeEquals(*presented, admin_token_);
  std::size_t user = 0;  // 1 + the index of the matching user token, 0 for none
  for (std::size_t i = 0; i < tokens_.size(); ++i) {
    if (ConstantTimeEquals(*presented, tokens_[i]) && user == 0) user = i + 1;
  }
  if (!is_admin && user == 0 && (user_required || admin_required)) {
    return absl::UnauthenticatedError("invalid bearer token");
  }
  if (admin_required && !is_admin) {
    return absl::PermissionDeniedError("this RPC needs the admin token");
  }
  if (is_admin) return std::string("admin");
  return user > 0 ? absl::StrCat("token ", user) : std::string();
}

absl::StatusOr<std::string> TokenAuthenticator::Authenticate(const grpc::ServerContextBase& context,
                                                             Access access) const {
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  if (it == metadata.end()) return Authenticate(std::nullopt, access);
  return Authenticate(std::string_view(it->second.data(), it->second.size()), access);
}

}  // namespace mlsreg::server
