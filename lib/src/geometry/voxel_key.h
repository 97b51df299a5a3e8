// The integer key of the voxel a point falls in, and its hash (shared by the voxel samplers).
#pragma once

#include <cmath>
#include <cstdint>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg::internal {

struct VoxelKey {
  std::int64_t x, y, z;
  bool operator==(const VoxelKey&) const = default;
};

struct VoxelKeyHash {
  std::size_t operator()(const VoxelKey& k) const {
    std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<std::uint64_t>(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= static_cast<std::uint64_t>(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

// The voxel of edge 1 / inv_voxel holding `p`.
inline VoxelKey KeyOf(const Vec3& p, double inv_voxel) {
  const Vec3 scaled = p * inv_voxel;
  return {static_cast<std::int64_t>(std::floor(scaled.x())),
          static_cast<std::int64_t>(std::floor(scaled.y())),
          static_cast<std::int64_t>(std::floor(scaled.z()))};
}

}  // namespace mlsreg::internal
