#include "lzf.h"

#include "absl/strings/str_cat.h"

namespace mlsreg::io_internal {

absl::StatusOr<std::string> LzfDecompress(std::string_view compressed, std::size_t size) {
  std::string out(size, '\0');
  std::size_t in = 0, at = 0;
  const auto corrupt = [&](std::size_t run, const char* what) {
    return absl::InvalidArgumentError(
        absl::StrCat("LZF data corrupt at byte ", run, " of ", compressed.size(), ": ", what));
  };
  while (in < compressed.size()) {
    const std::size_t run = in;
    const auto control = static_cast<unsigned char>(compressed[in++]);
    if (control < 32) {  // literal run
      const std::size_t length = std::size_t{control} + 1;
      if (length > compressed.size() - in) return corrupt(run, "a literal run is cut short");
      if (length > size - at) return corrupt(run, "a literal run goes past the declared size");
      out.replace(at, length, compressed.substr(in, length));
      in += length;
      at += length;
      continue;
    }
    std::size_t length = control >> 5;
    if (length == 7) {
      if (in == compressed.size()) return corrupt(run, "a back reference is cut short");
      length += static_cast<unsigned char>(compressed[in++]);
    }
    if (in == compressed.size()) return corrupt(run, "a back reference is cut short");
    const std::size_t distance =
        ((std::size_t{control} & 31) << 8) + static_cast<unsigned char>(compressed[in++]) + 1;
    length += 2;
    if (distance > at) return corrupt(run, "a back reference points before the start");
    if (length > size - at) return corrupt(run, "a back reference goes past the declared size");
    for (std::size_t k = 0; k < length; ++k, ++at) out[at] = out[at - distance];  // may overlap
  }
  if (at != size) {
    return absl::InvalidArgumentError(
        absl::StrCat("LZF data decompress to ", at, " bytes, not the ", size, " declared"));
  }
  return out;
}

}  // namespace mlsreg::io_internal
