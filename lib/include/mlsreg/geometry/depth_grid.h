// DepthGrid: the organised structure of a scan taken by a pinhole camera, needed by reverse
// calibration (RC-BL, RC-P). The scan is in its camera's frame: camera at the origin looking
// along +z, pixel (u, v) = (fx x / z + cx, fy y / z + cy).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

// The depth image of a cloud of n points may have at most max(kMinGridPixelCap,
// kMaxGridPixelsPerPoint * n) pixels: a scan fills a good share of its image, and the cap keeps
// a request of a few points from allocating a grid of gigabytes (4 bytes per pixel).
inline constexpr std::uint64_t kMaxGridPixelsPerPoint = 64;
inline constexpr std::uint64_t kMinGridPixelCap = std::uint64_t{1} << 16;
std::uint64_t MaxGridPixels(std::uint64_t point_count);
// Bytes the grid of these intrinsics takes.
std::uint64_t GridBytes(const PinholeIntrinsics& k);
// ValidateIntrinsics plus the pixel cap for `point_count` points (InvalidArgument naming `field`).
absl::Status ValidateIntrinsicsFor(const PinholeIntrinsics& k, std::uint64_t point_count,
                                   std::string_view field);

class DepthGrid {
 public:
  // Assigns every point with z > 0 to the pixel it projects to (the nearest point wins a pixel).
  // InvalidArgument when the intrinsics are invalid, the image exceeds MaxGridPixels or no point
  // lands in the image.
  static absl::StatusOr<DepthGrid> Build(const std::vector<Vec3>& points,
                                         const PinholeIntrinsics& intrinsics);

  const PinholeIntrinsics& intrinsics() const { return k_; }
  // Index of the point at pixel (u, v), or -1 for an empty pixel or outside the image.
  std::int32_t At(int u, int v) const {
    if (u < 0 || v < 0 || u >= k_.width || v >= k_.height) return -1;
    return pixels_[static_cast<std::size_t>(v) * k_.width + u];
  }
  // Real-valued pixel coordinates of a point in the camera frame; false behind the camera.
  bool Project(const Vec3& p, double& u, double& v) const;
  std::size_t MemoryBytes() const { return pixels_.capacity() * sizeof(std::int32_t); }

 private:
  PinholeIntrinsics k_;
  std::vector<std::int32_t> pixels_;
};

}  // namespace mlsreg
