// Identifiers that arrive from clients. They end up in file names and log lines, so only a
// conservative character set is accepted.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace mlsreg::server {

// 1-128 characters of [A-Za-z0-9._-], not starting with '.' (ids are file names in the data
// directory); INVALID_ARGUMENT naming `field` otherwise.
absl::Status ValidateTargetId(std::string_view id, std::string_view field);

// Client-chosen request ids: 1-128 characters of [A-Za-z0-9._:-].
absl::Status ValidateRequestId(std::string_view id, std::string_view field);

// A fresh id ("req-" + 16 hex digits), unique within this process and unlikely across servers.
std::string NewRequestId();

}  // namespace mlsreg::server
