#include "mlsreg/correspondences/correspondence_filter.h"

#include <algorithm>
#include <cmath>

namespace mlsreg {

void CorrespondenceCounts::Add(PairFate fate) {
  // Each fate's bucket, in PairFate's order.
  static constexpr int CorrespondenceCounts::*kBucket[] = {
      &CorrespondenceCounts::invalid, &CorrespondenceCounts::rejected_distance,
      &CorrespondenceCounts::rejected_normal, &CorrespondenceCounts::rejected_curvature,
      &CorrespondenceCounts::matched};
  ++(this->*kBucket[static_cast<std::size_t>(fate)]);
}

CorrespondenceCounts& CorrespondenceCounts::operator+=(const CorrespondenceCounts& other) {
  matched += other.matched;
  rejected_normal += other.rejected_normal;
  rejected_curvature += other.rejected_curvature;
  rejected_distance += other.rejected_distance;
  invalid += other.invalid;
  return *this;
}

PairFate CorrespondenceFilter::Judge(const Vec3& point, const Vec3& normal, double curvature,
                                     bool source_valid, const Correspondence& c) const {
  if (!c.valid || !source_valid) return PairFate::kInvalid;
  if ((point - c.point).squaredNorm() > options_.max_distance * options_.max_distance) {
    return PairFate::kTooFar;
  }
  const bool signed_normals = options_.source_oriented && options_.target_oriented;
  const double dot = normal.dot(c.normal);
  if ((signed_normals ? dot : std::abs(dot)) < options_.min_normal_dot) {
    return PairFate::kNormalsDisagree;
  }
  if (options_.min_curvature_ratio > 0.0) {
    const double h1 = std::max(curvature, options_.curvature_floor);
    const double h2 = std::max(c.curvature, options_.curvature_floor);
    const double ratio = h1 / h2;
    if (ratio < options_.min_curvature_ratio || ratio * options_.min_curvature_ratio > 1.0) {
      return PairFate::kCurvaturesDisagree;
    }
  }
  return PairFate::kMatched;
}

CorrespondenceCounts CorrespondenceFilter::Apply(
    std::span<const Vec3> points, std::span<const Vec3> normals, std::span<const double> curvature,
    std::span<const std::uint8_t> source_valid, std::span<const Correspondence> correspondences,
    std::span<std::uint8_t> accepted, std::span<PairFate> fates) const {
  CorrespondenceCounts counts;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const PairFate fate =
        Judge(points[i], normals[i], curvature[i], source_valid[i] != 0, correspondences[i]);
    accepted[i] = fate == PairFate::kMatched;
    if (!fates.empty()) fates[i] = fate;
    counts.Add(fate);
  }
  return counts;
}

}  // namespace mlsreg
