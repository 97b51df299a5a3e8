// LZF decompression (Marc Lehmann's liblzf format), the compression of PCD's DATA
// binary_compressed. Not part of the public API (io_pcd.cc uses it).
//
// The format is a sequence of runs, each starting with a control byte c:
//   c < 32:  a literal run: the next c + 1 bytes are copied;
//   c >= 32: a back reference of length (c >> 5) + 2 (c >> 5 == 7: plus the next byte) to
//            offset ((c & 31) << 8) + next byte + 1 before the output's end.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace mlsreg::io_internal {

// Decompresses `compressed` into exactly `size` bytes. Every read and write is checked:
// InvalidArgument naming the offset in `compressed` where a run is cut short, reaches before the
// start of the output or past `size`, or when the output is not exactly `size` bytes long.
absl::StatusOr<std::string> LzfDecompress(std::string_view compressed, std::size_t size);

}  // namespace mlsreg::io_internal
