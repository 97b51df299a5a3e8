// Reading the packed point data that follows a header as CloudChunk messages, with the checks
// both upload paths (CreateTarget, Register) need.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "absl/status/statusor.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::server {

// Yields the next chunk of the stream, nullptr when the stream ended, or an error (a message
// that is not a chunk, a cancelled call).
using NextChunk = std::function<absl::StatusOr<const v1::CloudChunk*>()>;

// Collects exactly `expected` bytes: chunks in order (offset == bytes so far), each at most
// `max_chunk_bytes` of data. INVALID_ARGUMENT naming "<field>.data", "<field>.offset" or
// "<field>" (stream ended early).
absl::StatusOr<std::string> ReadChunkedPayload(std::uint64_t expected, std::size_t max_chunk_bytes,
                                               const std::string& field,
                                               const NextChunk& next_chunk);

}  // namespace mlsreg::server
