// CorrespondenceFilter: rejects correspondences by distance, normal angle and curvature ratio
// (paper section 4), counting every rejection reason.
#pragma once

#include <cstdint>
#include <limits>
#include <span>

#include "mlsreg/correspondences/correspondence.h"

namespace mlsreg {

struct CorrespondenceFilterOptions {
  // Keep when <n_source, n_target> >= tau_N (paper: 0.7). When either side's normals have no
  // meaningful sign (no viewpoint known), |<n1, n2>| is compared instead. <= -1 disables.
  double min_normal_dot = 0.7;
  // Keep when tau_H <= H1/H2 <= 1/tau_H (paper: 0.75). 0 disables.
  double min_curvature_ratio = 0.75;
  // Surface variations below this floor are raised to it before the ratio test, so two nearly
  // flat patches (H ~ 1e-6 vs 1e-8) compare as equal instead of as a ratio of noise.
  double curvature_floor = 1e-4;
  // Keep when |p - q| <= max_distance (absolute units). Infinity disables (the default: Sparse
  // ICP's lp penalty handles outliers).
  double max_distance = std::numeric_limits<double>::infinity();
  // Whether the source normals have a meaningful sign.
  bool source_oriented = false;
  // Whether the target-side normals have a meaningful sign.
  bool target_oriented = false;
};

// What the filter made of one sample's correspondence, in the order it tests.
enum class PairFate : std::uint8_t {
  kInvalid,             // no usable partner (the finder's or the source's analysis failed)
  kTooFar,              // beyond max_distance
  kNormalsDisagree,     // normal angle beyond tau_N
  kCurvaturesDisagree,  // surface variation ratio outside [tau_H, 1 / tau_H]
  kMatched,
};

// What happened to one iteration's correspondences. Every sample lands in exactly one bucket.
struct CorrespondenceCounts {
  int matched = 0;
  int rejected_normal = 0;
  int rejected_curvature = 0;
  int rejected_distance = 0;
  int invalid = 0;  // the finder produced no usable partner (e.g. MLS projection failed)

  int total() const {
    return matched + rejected_normal + rejected_curvature + rejected_distance + invalid;
  }
  // Counts one sample of that fate.
  void Add(PairFate fate);
  CorrespondenceCounts& operator+=(const CorrespondenceCounts& other);
};

class CorrespondenceFilter {
 public:
  explicit CorrespondenceFilter(const CorrespondenceFilterOptions& options) : options_(options) {}

  // `points`, `normals`, `curvature`: the current (transformed) source samples, their normals
  // (rotated likewise) and surface variations; `source_valid[i]` is 0 where the source analysis
  // failed (counted as invalid). Writes accepted[i] = 1 for kept correspondences, and each
  // one's fate into `fates` when that is not empty.
  CorrespondenceCounts Apply(std::span<const Vec3> points, std::span<const Vec3> normals,
                             std::span<const double> curvature,
                             std::span<const std::uint8_t> source_valid,
                             std::span<const Correspondence> correspondences,
                             std::span<std::uint8_t> accepted,
                             std::span<PairFate> fates = {}) const;

  // The fate of one correspondence `c` of the sample at `point` (its normal and surface
  // variation; `source_valid` false where the source analysis failed). Apply judges each.
  PairFate Judge(const Vec3& point, const Vec3& normal, double curvature, bool source_valid,
                 const Correspondence& c) const;

  const CorrespondenceFilterOptions& options() const { return options_; }

 private:
  CorrespondenceFilterOptions options_;
};

}  // namespace mlsreg
