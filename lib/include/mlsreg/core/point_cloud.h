// PointCloud: the validated in-memory form of a scan.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "absl/status/status.h"

namespace mlsreg {

using Vec3 = Eigen::Vector3d;
// A colour, 8 bits per channel: red, green, blue.
using Rgb = std::array<std::uint8_t, 3>;

// Positions (and optionally normals) of one scan, in double precision, contiguous.
// A pinhole camera: pixel (u, v) = (fx x / z + cx, fy y / z + cy) for a point in its frame.
struct PinholeIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
};

struct PointCloud {
  std::vector<Vec3> points;
  // Empty, or one unit normal per point.
  std::vector<Vec3> normals = {};
  // Empty, or one colour per point, as read from a file (PLY red green blue, PCD rgb, text r g
  // b). Registration never looks at them; they are carried to the clouds mlsreg writes.
  std::vector<Rgb> colors = {};
  // The sensor origin in this cloud's frame, when the file says where it was (PCD VIEWPOINT, or
  // set by the caller). Normals are oriented toward it when known.
  std::optional<Vec3> viewpoint = {};
  // Set for an organised scan taken by a pinhole camera, with the cloud in the camera's frame
  // (camera at the origin looking along +z). Needed by reverse calibration (RC-BL, RC-P).
  std::optional<PinholeIntrinsics> intrinsics = {};

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_colors() const { return !colors.empty(); }
};

// Checks the invariants every consumer relies on: at least `min_points` points, all coordinates
// finite, normals either absent or one per point and finite, colours absent or one per point. The
// message names the first offending point index.
absl::Status ValidatePointCloud(const PointCloud& cloud, std::size_t min_points = 1);

// Positive size (at most 100000 x 100000) and focal lengths, finite principal point; the
// message names `field`.
absl::Status ValidateIntrinsics(const PinholeIntrinsics& k, std::string_view field);

// Registration refuses coordinates beyond this magnitude (files may hold any finite value): their
// squared distances overflow or keep no precision at any sampling distance a scan can have.
inline constexpr double kMaxAbsCoordinate = 1e12;
// InvalidArgument naming the first point with a coordinate beyond kMaxAbsCoordinate.
absl::Status CheckCoordinateRange(const PointCloud& cloud);

}  // namespace mlsreg
