// WeightedCovariance: accumulate weighted points, then finalize into a local PCA frame.
#pragma once

#include <Eigen/Core>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

// The result of a weighted principal component analysis of a neighbourhood.
struct LocalFrame {
  Vec3 mean = Vec3::Zero();     // weighted mean of the neighbours
  Vec3 normal = Vec3::UnitZ();  // eigenvector of the smallest eigenvalue (sign arbitrary)
  Vec3 tangent_u = Vec3::UnitX();
  Vec3 tangent_v = Vec3::UnitY();
  Vec3 eigenvalues = Vec3::Zero();  // ascending: lambda1 <= lambda2 <= lambda3
  // Surface variation H = lambda1 / (lambda1 + lambda2 + lambda3) (paper Eq. 8), in [0, 1/3].
  double surface_variation = 0.0;
};

// Ponca-style accumulate/finalize fit. Positions are accumulated relative to a caller-chosen
// origin close to the neighbourhood (e.g. the query point), which keeps the covariance well
// conditioned whatever the absolute coordinates are.
class WeightedCovariance {
 public:
  explicit WeightedCovariance(const Vec3& origin) : origin_(origin) {}

  void Add(const Vec3& point, double weight) {
    const Vec3 d = point - origin_;
    sum_w_ += weight;
    sum_wd_ += weight * d;
    sum_wdd_.noalias() += weight * d * d.transpose();
    ++count_;
  }

  int count() const { return count_; }
  double total_weight() const { return sum_w_; }

  // False when fewer than 3 points carry weight, or the neighbourhood is degenerate (all points on
  // a line or one point: the middle eigenvalue vanishes relative to the largest).
  bool Finalize(LocalFrame& frame) const;

 private:
  Vec3 origin_;
  double sum_w_ = 0.0;
  Vec3 sum_wd_ = Vec3::Zero();
  Eigen::Matrix3d sum_wdd_ = Eigen::Matrix3d::Zero();
  int count_ = 0;
};

}  // namespace mlsreg
