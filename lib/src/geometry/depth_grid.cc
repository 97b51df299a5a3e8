#include "mlsreg/geometry/depth_grid.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlsreg {

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
