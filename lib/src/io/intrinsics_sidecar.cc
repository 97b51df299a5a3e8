#include "mlsreg/io/intrinsics_sidecar.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "mlsreg/io/io.h"

namespace mlsreg {

absl::StatusOr<PinholeIntrinsics> ParseIntrinsics(std::string_view text, std::string_view source) {
  const std::string where(source);
  std::vector<double> numbers;
  std::istringstream lines{std::string(text)};
  std::string line;
  while (std::getline(lines, line)) {
    line = line.substr(0, line.find('#'));
    std::istringstream words(line);
    std::string word;
    while (words >> word) {
      double value = 0.0;
      const auto [ptr, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
      if (ec != std::errc() || ptr != word.data() + word.size()) {
        return absl::InvalidArgumentError(absl::StrCat(where, ": '", word, "' is not a number"));
      }
      if (numbers.size() == 6) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ": needs 6 numbers (width height fx fy cx cy), found more"));
      }
      numbers.push_back(value);
    }
  }
  if (numbers.size() != 6) {
    return absl::InvalidArgumentError(absl::StrCat(
        where, ": needs 6 numbers (width height fx fy cx cy), found ", numbers.size()));
  }
  // Width and height must be whole numbers in range before they become ints.
  for (int i = 0; i < 2; ++i) {
    if (!(numbers[i] >= 1.0 && numbers[i] <= 100000.0) || numbers[i] != std::floor(numbers[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, ": width and height must be whole numbers in [1, 100000]"));
    }
  }
  PinholeIntrinsics k{static_cast<int>(numbers[0]),
                      static_cast<int>(numbers[1]),
                      numbers[2],
                      numbers[3],
                      numbers[4],
                      numbers[5]};
  if (absl::Status s = ValidateIntrinsics(k, where); !s.ok()) return s;
  return k;
}

absl::StatusOr<PinholeIntrinsics> ReadIntrinsicsSidecar(const std::string& scan_path) {
  const std::string path = scan_path + ".intrinsics";
  absl::StatusOr<std::string> text = ReadFileBytes(path);
  if (absl::IsNotFound(text.status())) {
    return absl::NotFoundError("no intrinsics sidecar '" + path + "'");
  }
  if (!text.ok()) return text.status();
  return ParseIntrinsics(*text, path);
}

std::string FormatIntrinsics(const PinholeIntrinsics& k) {
  return absl::StrFormat("# width height fx fy cx cy\n%d %d %.17g %.17g %.17g %.17g\n", k.width,
                         k.height, k.fx, k.fy, k.cx, k.cy);
}

}  // namespace mlsreg
