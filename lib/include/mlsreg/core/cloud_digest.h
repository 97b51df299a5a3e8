// CloudDigest: a content digest of a point cloud, so that a target can be identified by what it
// holds rather than by the name of the file it came from. "sha256:" + 64 hex digits over a
// versioned canonical form: the point count, every coordinate and normal component as a
// little-endian float64, then the viewpoint and the pinhole intrinsics when present. Two clouds
// have the same digest iff they hold the same numbers (bit for bit) in the same order.
#pragma once

#include <string>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

std::string CloudDigest(const PointCloud& cloud);

}  // namespace mlsreg
