#include "mlsreg/core/point_cloud.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace mlsreg {

absl::Status ValidatePointCloud(const PointCloud& cloud, std::size_t min_points) {
  if (cloud.size() < min_points) {
    return absl::InvalidArgumentError(absl::StrCat(
        "point cloud has ", cloud.size(), " points; at least ", min_points, " are required"));
  }
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (!cloud.points[i].allFinite()) {
      return absl::InvalidArgumentError(
          absl::StrCat("point ", i, " has a non-finite coordinate (NaN or Inf)"));
    }
  }
  if (cloud.has_normals()) {
    if (cloud.normals.size() != cloud.points.size()) {
      return absl::InvalidArgumentError(absl::StrCat("point cloud has ", cloud.points.size(),
                                                     " points but ", cloud.normals.size(),
                                                     " normals"));
    }
    for (std::size_t i = 0; i < cloud.normals.size(); ++i) {
      if (!cloud.normals[i].allFinite()) {
        return absl::InvalidArgumentError(
            absl::StrCat("normal ", i, " has a non-finite component (NaN or Inf)"));
      }
    }
  }
  if (cloud.has_colors() && cloud.colors.size() != cloud.points.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "point cloud has ", cloud.points.size(), " points but ", cloud.colors.size(), " colours"));
  }
  if (cloud.viewpoint && !cloud.viewpoint->allFinite()) {
    return absl::InvalidArgumentError("viewpoint has a non-finite coordinate");
  }
  return absl::OkStatus();
}

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

absl::Status CheckCoordinateRange(const PointCloud& cloud) {
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const double magnitude = cloud.points[i].cwiseAbs().maxCoeff();
    if (magnitude > kMaxAbsCoordinate) {
      return absl::InvalidArgumentError(absl::StrCat(
          "point ", i, " has a coordinate of magnitude ", magnitude, ", beyond the limit of ",
          kMaxAbsCoordinate, " for registration (squared distances would overflow)"));
    }
  }
  return absl::OkStatus();
}

}  // namespace mlsreg
