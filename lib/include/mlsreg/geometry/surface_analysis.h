// Per-point normals and surface variation from Wendland-weighted local PCA.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

// Normal and surface variation H (paper Eq. 8) at a set of points. `valid[i]` is 0 where the
// neighbourhood was too small or degenerate; normal/curvature are then zero and must not be used.
struct SurfaceProperties {
  std::vector<Vec3> normals;
  std::vector<double> curvature;
  std::vector<std::uint8_t> valid;
  // True when normals were oriented toward a known viewpoint, so their sign is meaningful.
  bool oriented = false;
  // True when the analysis was stopped part-way (the caller's StopCheck): nothing is usable.
  bool stopped = false;

  std::size_t size() const { return normals.size(); }
};

// Analyses `points[i]` for every i in `indices` (or every point when `indices` is empty) using the
// neighbours within `radius` (at most kMaxRadiusNeighbors, the nearest), weighted by the
// Wendland function. Normals point toward `viewpoint` when it is given. Allocation happens once
// per call and thread, not per point. `should_stop` is asked every few hundred points (from
// every thread). `threads` split the points (ParallelFor); the result does not depend on them.
SurfaceProperties AnalyzeSurface(const std::vector<Vec3>& points, const KdTree& tree, double radius,
                                 const std::optional<Vec3>& viewpoint,
                                 std::span<const std::uint32_t> indices = {},
                                 const StopCheck& should_stop = {}, int threads = 1);

}  // namespace mlsreg
