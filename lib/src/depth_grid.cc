#include "mlsreg/depth_grid.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlsreg {

absl::Status ValidateIntrinsics(const PinholeIntrinsics& k, std::string_view field) {
  const std::string f(field);
  if (k.width <= 0 || k.height <= 0 || k.width > 100000 || k.height > 100000) {
    return absl::InvalidArgumentError(f + ": width and height must be in [1, 100000]");
  }
  if (!(k.fx > 0.0 && k.fy > 0.0 && std::isfinite(k.fx) && std::isfinite(k.fy))) {
    return absl::InvalidArgumentError(f + ": focal lengths fx, fy must be positive");
  }
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) {
    return absl::InvalidArgumentError(f + ": principal point cx, cy must be finite");
  }
  return absl::OkStatus();
}

std::uint64_t MaxGridPixels(std::uint64_t point_count) {
  return std::max(kMinGridPixelCap, kMaxGridPixelsPerPoint * point_count);
}

std::uint64_t GridBytes(const PinholeIntrinsics& k) {
  if (k.width <= 0 || k.height <= 0) return 0;
  return static_cast<std::uint64_t>(k.width) * static_cast<std::uint64_t>(k.height) *
         sizeof(std::int32_t);
}

absl::Status ValidateIntrinsicsFor(const PinholeIntrinsics& k, std::uint64_t point_count,
                                   std::string_view field) {
  if (absl::Status s = ValidateIntrinsics(k, field); !s.ok()) return s;
  const std::uint64_t pixels = static_cast<std::uint64_t>(k.width) * k.height;
  if (pixels > MaxGridPixels(point_count)) {
    return absl::InvalidArgumentError(absl::StrCat(
        std::string(field), ": a ", k.width, " x ", k.height, " image (", pixels,
        " pixels) is too large for ", point_count, " points (at most ", MaxGridPixels(point_count),
        " pixels: ", kMaxGridPixelsPerPoint, " per point, or ", kMinGridPixelCap, ")"));
  }
  return absl::OkStatus();
}

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
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError("no intrinsics sidecar '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseIntrinsics(text.str(), path);
}

std::string FormatIntrinsics(const PinholeIntrinsics& k) {
  return absl::StrFormat("# width height fx fy cx cy\n%d %d %.17g %.17g %.17g %.17g\n", k.width,
                         k.height, k.fx, k.fy, k.cx, k.cy);
}

bool DepthGrid::Project(const Vec3& p, double& u, double& v) const {
  if (!(p.z() > 0.0)) return false;
  u = k_.fx * p.x() / p.z() + k_.cx;
  v = k_.fy * p.y() / p.z() + k_.cy;
  return std::isfinite(u) && std::isfinite(v);
}

absl::StatusOr<DepthGrid> DepthGrid::Build(const std::vector<Vec3>& points,
                                           const PinholeIntrinsics& intrinsics) {
  if (absl::Status s = ValidateIntrinsicsFor(intrinsics, points.size(), "intrinsics"); !s.ok()) {
    return s;
  }
  DepthGrid grid;
  grid.k_ = intrinsics;
  grid.pixels_.assign(static_cast<std::size_t>(intrinsics.width) * intrinsics.height, -1);
  std::size_t placed = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    double u, v;
    if (!grid.Project(points[i], u, v)) continue;
    const long iu = std::lround(u), iv = std::lround(v);
    if (iu < 0 || iv < 0 || iu >= intrinsics.width || iv >= intrinsics.height) continue;
    std::int32_t& pixel = grid.pixels_[static_cast<std::size_t>(iv) * intrinsics.width + iu];
    if (pixel < 0) ++placed;
    if (pixel < 0 || points[i].z() < points[pixel].z()) pixel = static_cast<std::int32_t>(i);
  }
  if (placed == 0) {
    return absl::InvalidArgumentError("intrinsics: no point of the cloud projects into the image");
  }
  return grid;
}

}  // namespace mlsreg
