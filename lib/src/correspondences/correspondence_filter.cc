#include "mlsreg/correspondences/correspondence_filter.h"

#include <algorithm>
#include <cmath>

namespace mlsreg {

CorrespondenceCounts CorrespondenceFilter::Apply(std::span<const Vec3> points,
                                                 std::span<const Vec3> normals,
                                                 std::span<const double> curvature,
                                                 std::span<const std::uint8_t> source_valid,
                                                 std::span<const Correspondence> correspondences,
                                                 std::span<std::uint8_t> accepted) const {
  const bool signed_normals = options_.source_oriented && options_.target_oriented;
  const double max_distance_squared = options_.max_distance * options_.max_distance;
  const bool use_curvature = options_.min_curvature_ratio > 0.0;
  CorrespondenceCounts counts;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const Correspondence& c = correspondences[i];
    accepted[i] = 0;
    if (!c.valid || !source_valid[i]) {
      ++counts.invalid;
      continue;
    }
    if ((points[i] - c.point).squaredNorm() > max_distance_squared) {
      ++counts.rejected_distance;
      continue;
    }
    const double dot = normals[i].dot(c.normal);
    if ((signed_normals ? dot : std::abs(dot)) < options_.min_normal_dot) {
      ++counts.rejected_normal;
      continue;
    }
    if (use_curvature) {
      const double h1 = std::max(curvature[i], options_.curvature_floor);
      const double h2 = std::max(c.curvature, options_.curvature_floor);
      const double ratio = h1 / h2;
      if (ratio < options_.min_curvature_ratio || ratio * options_.min_curvature_ratio > 1.0) {
        ++counts.rejected_curvature;
        continue;
      }
    }
    accepted[i] = 1;
    ++counts.matched;
  }
  return counts;
}

}  // namespace mlsreg
