#include "mlsreg/geometry/surface_analysis.h"

#include <cmath>

#include "mlsreg/core/parallel_for.h"
#include "mlsreg/geometry/weighted_covariance.h"
#include "mlsreg/geometry/wendland.h"

namespace mlsreg {

SurfaceProperties AnalyzeSurface(const std::vector<Vec3>& points, const KdTree& tree, double radius,
                                 const std::optional<Vec3>& viewpoint,
                                 std::span<const std::uint32_t> indices,
                                 const StopCheck& should_stop, int threads) {
  const std::size_t n = indices.empty() ? points.size() : indices.size();
  SurfaceProperties out;
  out.normals.assign(n, Vec3::Zero());
  out.curvature.assign(n, 0.0);
  out.valid.assign(n, 0);
  out.oriented = viewpoint.has_value();

  const bool finished = ParallelForUntilStopped<RadiusNeighbors>(
      n, threads, should_stop, [&](std::size_t i, RadiusNeighbors& neighbors) {
        const Vec3& p = points[indices.empty() ? i : indices[i]];
        tree.Radius(p, radius, neighbors);
        WeightedCovariance fit(p);
        for (const auto& [index, d2] : neighbors) {
          fit.Add(points[index], WendlandWeight(std::sqrt(d2), radius));
        }
        LocalFrame frame;
        if (!fit.Finalize(frame)) return;
        Vec3 normal = frame.normal;
        if (viewpoint && normal.dot(*viewpoint - p) < 0.0) normal = -normal;
        out.normals[i] = normal;
        out.curvature[i] = frame.surface_variation;
        out.valid[i] = 1;
      });
  out.stopped = !finished;
  return out;
}

}  // namespace mlsreg
