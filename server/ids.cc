#include "server/ids.h"

#include <atomic>
#include <cstdint>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlsreg::server {
namespace {

absl::Status ValidateId(std::string_view id, const std::string& field, std::string_view extra,
                        const std::string& allowed) {
  if (id.empty() || id.size() > 128) {
    return absl::InvalidArgumentError(
        absl::StrCat(field, ": must be 1-128 characters long (got ", id.size(), ")"));
  }
  for (std::size_t i = 0; i < id.size(); ++i) {
    const char c = id[i];
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    extra.find(c) != std::string_view::npos;
    if (!ok) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ": character ", i, " is not allowed (use ", allowed, ")"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateTargetId(std::string_view id, std::string_view field) {
  if (!id.empty() && id.front() == '.') {
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(field), ": must not start with '.'"));
  }
  return ValidateId(id, std::string(field), "._-", "[A-Za-z0-9._-]");
}

absl::Status ValidateRequestId(std::string_view id, std::string_view field) {
  return ValidateId(id, std::string(field), "._:-", "[A-Za-z0-9._:-]");
}

std::string NewRequestId() {
  // A random per-process base plus a counter: unique here, and servers rarely collide.
  static const std::uint64_t base = std::random_device{}() * 0x9E3779B97F4A7C15ull;
  static std::atomic<std::uint64_t> counter{0};
  return absl::StrFormat("req-%016x", base + counter.fetch_add(1));
}

}  // namespace mlsreg::server
