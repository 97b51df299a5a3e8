// SurfaceCache: one cloud's surface properties (surface_analysis.h), each point analysed once.
// Method auto refines the same source several times (the start, global candidates, MLS-SICP
// alone, the finish over every point); each refinement asks for the normals and surface
// variation at its samples at the same radius. The cache analyses a point on the first request
// and hands out the stored values after, so every request gets exactly what AnalyzeSurface
// would have returned for it (a point's properties depend only on its own neighbourhood).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/surface_analysis.h"

namespace mlsreg {

class SurfaceCache {
 public:
  // `points` and `tree` (their index) must outlive the cache.
  SurfaceCache(const std::vector<Vec3>& points, const KdTree& tree,
               const std::optional<Vec3>& viewpoint);

  // AnalyzeSurface(points, tree, radius, viewpoint, indices, should_stop, threads), analysing
  // only the points no earlier request at this radius analysed. A request at another radius
  // starts the cache over. Not thread-safe (one registration asks at a time); `threads` split
  // the points analysed now.
  SurfaceProperties At(double radius, std::span<const std::uint32_t> indices,
                       const StopCheck& should_stop, int threads);

  std::size_t analysed() const { return analysed_count_; }

 private:
  const std::vector<Vec3>* points_;
  const KdTree* tree_;
  std::optional<Vec3> viewpoint_;
  double radius_ = 0.0;
  std::vector<std::uint8_t> analysed_;  // per point
  std::size_t analysed_count_ = 0;
  SurfaceProperties all_;  // per point; meaningful where analysed_
};

}  // namespace mlsreg
