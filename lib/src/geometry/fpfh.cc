#include "mlsreg/geometry/fpfh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "mlsreg/core/parallel_for.h"

namespace mlsreg {
namespace {

constexpr int kBins = 11;

// The three angular features of a point pair (Rusu 2009, as computed by PCL's
// computePairFeatures): the point whose normal is closer to the connecting line is the source.
bool PairFeatures(const Vec3& p1, const Vec3& n1, const Vec3& p2, const Vec3& n2, double& f1,
                  double& f2, double& f3) {
  Vec3 d = p2 - p1;
  const double length = d.norm();
  if (length <= 0.0) return false;
  Vec3 u = n1, other = n2;
  const double angle1 = n1.dot(d) / length, angle2 = n2.dot(d) / length;
  if (std::acos(std::abs(angle1)) > std::acos(std::abs(angle2))) {
    u = n2;
    other = n1;
    d = -d;
    f3 = -angle2;
  } else {
    f3 = angle1;
  }
  Vec3 v = d.cross(u);
  const double v_norm = v.norm();
  if (v_norm <= 0.0) return false;
  v /= v_norm;
  const Vec3 w = u.cross(v);
  f2 = v.dot(other);
  f1 = std::atan2(w.dot(other), u.dot(other));
  return true;
}

int Bin(double value, double lo, double hi) {
  const int b = static_cast<int>(std::floor(kBins * (value - lo) / (hi - lo)));
  return std::clamp(b, 0, kBins - 1);
}

void NormalizeBlocks(FpfhFeature& h) {
  for (int block = 0; block < 3; ++block) {
    float sum = 0.0f;
    for (int b = 0; b < kBins; ++b) sum += h[block * kBins + b];
    if (sum > 0.0f) {
      for (int b = 0; b < kBins; ++b) h[block * kBins + b] *= 100.0f / sum;
    }
  }
}

}  // namespace

namespace {

// body(i, neighbours of i) for every point on `threads`; false when `should_stop` said stop.
template <typename Body>
bool ForEachNeighbourhood(const std::vector<Vec3>& points, const KdTree& tree, double radius,
                          const StopCheck& should_stop, int threads, Body&& body) {
  return ParallelForUntilStopped<RadiusNeighbors>(
      points.size(), threads, should_stop, [&](std::size_t i, RadiusNeighbors& neighbors) {
        tree.Radius(points[i], radius, neighbors, kMaxFpfhNeighbors);
        body(i, neighbors);
      });
}

}  // namespace

std::vector<FpfhFeature> ComputeFpfh(const std::vector<Vec3>& points,
                                     const std::vector<Vec3>& normals, const KdTree& tree,
                                     double radius, const StopCheck& should_stop, int threads) {
  const std::size_t n = points.size();
  std::vector<FpfhFeature> spfh(n), fpfh(n);
  // Each point's own histogram (SPFH), then each weighted with its neighbours' (FPFH): every
  // point's value depends on the points alone, so it is the same for any thread count.
  const bool spfh_done = ForEachNeighbourhood(
      points, tree, radius, should_stop, threads,
      [&](std::size_t i, const RadiusNeighbors& neighbors) {
        FpfhFeature& h = spfh[i];
        h.fill(0.0f);
        for (const auto& [j, d2] : neighbors) {
          if (j == i) continue;
          double f1, f2, f3;
          if (!PairFeatures(points[i], normals[i], points[j], normals[j], f1, f2, f3)) continue;
          h[Bin(f1, -std::numbers::pi, std::numbers::pi)] += 1.0f;
          h[kBins + Bin(f2, -1.0, 1.0)] += 1.0f;
          h[2 * kBins + Bin(f3, -1.0, 1.0)] += 1.0f;
        }
        NormalizeBlocks(h);
      });
  if (!spfh_done) return {};
  const bool fpfh_done = ForEachNeighbourhood(points, tree, radius, should_stop, threads,
                                              [&](std::size_t i, const RadiusNeighbors& neighbors) {
                                                FpfhFeature& h = fpfh[i];
                                                h = spfh[i];
                                                int k = 0;
                                                FpfhFeature weighted{};
                                                for (const auto& [j, d2] : neighbors) {
                                                  if (j == i || d2 <= 0.0) continue;
                                                  // 1/distance as in Rusu 2009, with distances in
                                                  // units of the radius (scale-free).
                                                  const float weight =
                                                      static_cast<float>(radius / std::sqrt(d2));
                                                  for (int b = 0; b < 33; ++b)
                                                    weighted[b] += weight * spfh[j][b];
                                                  ++k;
                                                }
                                                if (k > 0) {
                                                  for (int b = 0; b < 33; ++b)
                                                    h[b] += weighted[b] / static_cast<float>(k);
                                                }
                                                NormalizeBlocks(h);
                                              });
  if (!fpfh_done) return {};
  return fpfh;
}

}  // namespace mlsreg
