// One-line log records on stderr ("2026-11-23T16:53:29.123Z mlsreg <message>"). Each record is
// written with a single call, so lines from concurrent handlers do not interleave.
#pragma once

#include <string_view>

namespace mlsreg::server {

void LogLine(std::string_view message);

}  // namespace mlsreg::server
