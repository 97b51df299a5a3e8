#include "server/chunked_payload.h"

#include "absl/strings/str_cat.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg::server {

absl::StatusOr<std::string> ReadChunkedPayload(std::uint64_t expected, std::size_t max_chunk_bytes,
                                               const std::string& field,
                                               const NextChunk& next_chunk) {
  wire::PayloadAssembler assembler(expected, field);
  while (!assembler.complete()) {
    absl::StatusOr<const v1::CloudChunk*> chunk = next_chunk();
    if (!chunk.ok()) return chunk.status();
    if (*chunk == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat(field, ": the stream ended after ",
                                                     assembler.received(), " of ", expected,
                                                     " declared bytes"));
    }
    // Checked before appending: the limit is what keeps one message's memory bounded.
    if ((*chunk)->data().size() > max_chunk_bytes) {
      return absl::InvalidArgumentError(absl::StrCat(field, ".data: ", (*chunk)->data().size(),
                                                     " bytes exceed the limit of ", max_chunk_bytes,
                                                     " bytes per chunk"));
    }
    if (absl::Status s = assembler.Append(**chunk); !s.ok()) return s;
  }
  return assembler.Release();
}

}  // namespace mlsreg::server
