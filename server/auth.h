// TokenAuthenticator: bearer-token checks done at the start of every handler. Tokens come from
// the `authorization: Bearer <token>` metadata. (gRPC's AuthMetadataProcessor only runs on
// secure credentials, and plaintext behind a TLS-terminating proxy is a supported deployment,
// so the check lives in the handlers.)
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

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
  // `tokens`: the user tokens, one per line (a token file may give each client its own; blank
  // lines are skipped). Empty: no user token is required.
  TokenAuthenticator(std::string_view tokens, std::string admin_token);

  // `authorization` is the metadata value, nullopt when absent. Returns who is calling, as the
  // per-client stream limit counts them: "token N" for the N-th user token (from 1), "admin" for
  // the admin token, "" when no token was presented (none is required). UNAUTHENTICATED when a
  // required token is missing or no configured token matches; PERMISSION_DENIED when a valid
  // user token (or no token, if none is required) asks for admin access.
  absl::StatusOr<std::string> Authenticate(std::optional<std::string_view> authorization,
                                           Access access) const;
  // The same, reading the metadata of a call.
  absl::StatusOr<std::string> Authenticate(const grpc::ServerContextBase& context,
                                           Access access) const;

  absl::Status Check(std::optional<std::string_view> authorization, Access access) const {
    return Authenticate(authorization, access).status();
  }

 private:
  std::vector<std::string> tokens_;
  std::string admin_token_;
};

// Compares in time that depends only on the length of `secret`, so response times do not
// reveal how many leading characters of a guess were right.
bool ConstantTimeEquals(std::string_view given, std::string_view secret);

}  // namespace mlsreg::server
