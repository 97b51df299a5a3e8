#include "mlsreg/geometry/surface_cache.h"

#include <numeric>

namespace mlsreg {

SurfaceCache::SurfaceCache(const std::vector<Vec3>& points, const KdTree& tree,
                           const std::optional<Vec3>& viewpoint)
    : points_(&points), tree_(&tree), viewpoint_(viewpoint) {}

SurfaceProperties SurfaceCache::At(double radius, std::span<const std::uint32_t> indices,
                                   const StopCheck& should_stop, int threads) {
  const std::size_t n = points_->size();
  if (radius != radius_ || analysed_.size() != n) {
    radius_ = radius;
    analysed_.assign(n, 0);
    analysed_count_ = 0;
    all_.normals.assign(n, Vec3::Zero());
    all_.curvature.assign(n, 0.0);
    all_.valid.assign(n, 0);
    all_.oriented = viewpoint_.has_value();
  }
  std::vector<std::uint32_t> every;
  if (indices.empty()) {
    every.resize(n);
    std::iota(every.begin(), every.end(), 0u);
    indices = every;
  }
  std::vector<std::uint32_t> missing;
  for (const std::uint32_t i : indices) {
    if (!analysed_[i]) missing.push_back(i);
  }
  SurfaceProperties out;
  out.oriented = all_.oriented;
  if (!missing.empty()) {
    const SurfaceProperties fresh =
        AnalyzeSurface(*points_, *tree_, radius, viewpoint_, missing, should_stop, threads);
    if (fresh.stopped) {
      out.stopped = true;
      return out;
    }
    for (std::size_t k = 0; k < missing.size(); ++k) {
      const std::uint32_t i = missing[k];
      all_.normals[i] = fresh.normals[k];
      all_.curvature[i] = fresh.curvature[k];
      all_.valid[i] = fresh.valid[k];
      analysed_[i] = 1;
    }
    analysed_count_ += missing.size();
  }
  out.normals.reserve(indices.size());
  out.curvature.reserve(indices.size());
  out.valid.reserve(indices.size());
  for (const std::uint32_t i : indices) {
    out.normals.push_back(all_.normals[i]);
    out.curvature.push_back(all_.curvature[i]);
    out.valid.push_back(all_.valid[i]);
  }
  return out;
}

}  // namespace mlsreg
