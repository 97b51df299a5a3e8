// TokenAuthenticator: bearer-token checks done at the start of every handler. Tokens come from
// the `authorization: Bearer <token>` metadata. (gRPC's AuthMetadataProcessor only runs on
// secure credentials, and plaintext behind a TLS-terminating proxy is a supported deployment,
// so the check lives in the handlers.)
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace grpc {
class ServerContextBase;
}

namespace mlsreg::server {

enum class Access {
  kUser,   // every RPC: needs `token` (or the admin token) when a token is configured
  kAdmin,  // DeleteTarget: needs `admin_token` when one is configured
};

class TokenAuthenticator {
 public:
  TokenAuthenticator(std::string token, std::string admin_token)
      : token_(std::move(token)), admin_token_(std::move(admin_token)) {}

  // `authorization` is the metadata value, nullopt when absent. UNAUTHENTICATED when a required
  // token is missing or no configured token matches; PERMISSION_DENIED when a valid user token
  // (or no token, if none is required) asks for admin access.
  absl::Status Check(std::optional<std::string_view> authorization, Access access) const;

  // The same, reading the metadata of a call.
  absl::Status Check(const grpc::ServerContextBase& context, Access access) const;

 private:
  std::string token_;
  std::string admin_token_;
};

// Compares in time that depends only on the length of `secret`, so response times do not
// reveal how many leading characters of a guess were right.
bool ConstantTimeEquals(std::string_view given, std::string_view secret);

}  // namespace mlsreg::server
