// NeighborCache: a query's nearest neighbours kept for its next query nearby.
//
// An ICP loop asks, for each sample, the nearest target points at every iteration, and an
// iteration moves a sample by a fraction of the spacing. A cache holds the M points nearest an
// earlier query point c and the distance d_M within which it holds every point. A later query p
// whose k nearest cached points all lie within d_M - |p - c| of p is answered from the cache:
// every point outside it lies at least that far from p. Otherwise the tree is searched again and
// the cache refilled around p. Either way the answer is the tree's, ordered by (distance, index).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

template <int M>
struct NeighborCache {
  static constexpr int kSize = M;
  Vec3 center = Vec3::Zero();
  double reach = -1.0;  // every point within `reach` of `center` is cached; negative: empty
  int count = 0;
  std::uint32_t index[M];
};

namespace neighbor_cache_internal {

struct Candidate {
  double distance_squared;
  std::uint32_t index;
  bool operator<(const Candidate& other) const {
    return distance_squared != other.distance_squared ? distance_squared < other.distance_squared
                                                      : index < other.index;
  }
};

// Distances of `count` candidates to `query`, the `k` nearest sorted to the front; how many.
inline int SelectNearest(const std::vector<Vec3>& points, const Vec3& query, int k,
                         Candidate* candidates, int count) {
  for (int j = 0; j < count; ++j) {
    candidates[j].distance_squared = (points[candidates[j].index] - query).squaredNorm();
  }
  const int n = std::min(count, k);
  std::partial_sort(candidates, candidates + n, candidates + count);
  return n;
}

}  // namespace neighbor_cache_internal

// The k <= M nearest of `points` (indexed by `tree`) to `query`, sorted by (distance, index),
// into `index` and `distance_squared`; returns how many (fewer only when the tree holds fewer).
// With `cache` null the tree is searched for k; otherwise the cache answers when it can and is
// refilled (M points around `query`) when it cannot. Allocation-free.
template <int M>
std::size_t CachedKnn(const KdTree& tree, const std::vector<Vec3>& points, const Vec3& query, int k,
                      NeighborCache<M>* cache, std::uint32_t* index, double* distance_squared) {
  using neighbor_cache_internal::Candidate;
  using neighbor_cache_internal::SelectNearest;
  Candidate candidates[M];
  const auto write = [&](int n) {
    for (int j = 0; j < n; ++j) {
      index[j] = candidates[j].index;
      distance_squared[j] = candidates[j].distance_squared;
    }
    return static_cast<std::size_t>(n);
  };
  if (cache != nullptr && cache->reach >= 0.0) {
    for (int j = 0; j < cache->count; ++j) candidates[j].index = cache->index[j];
    const int n = SelectNearest(points, query, k, candidates, cache->count);
    // Every point outside the cache lies at least `limit` from `query`.
    const double limit = cache->reach - (query - cache->center).norm();
    if (n > 0 && (std::isinf(limit) ||
                  (limit > 0.0 && candidates[n - 1].distance_squared <= limit * limit))) {
      return write(n);
    }
  }
  const int asked = cache != nullptr ? M : k;
  std::uint32_t found_index[M];
  double found_distance_squared[M];
  const int count = static_cast<int>(tree.Knn(query, asked, found_index, found_distance_squared));
  for (int j = 0; j < count; ++j) candidates[j].index = found_index[j];
  if (cache != nullptr) {
    cache->center = query;
    cache->count = count;
    for (int j = 0; j < count; ++j) cache->index[j] = found_index[j];
    // Slightly inside the tree's M-th distance, so that its rounding never matters.
    cache->reach = count < M ? std::numeric_limits<double>::infinity()
                             : std::sqrt(found_distance_squared[count - 1]) * (1.0 - 1e-9);
  }
  return write(SelectNearest(points, query, k, candidates, count));
}

// The nearest of `points` to `query` through `cache` (as CachedKnn with k = 1). Requires a
// non-empty tree.
template <int M>
Neighbor CachedNearest(const KdTree& tree, const std::vector<Vec3>& points, const Vec3& query,
                       NeighborCache<M>& cache) {
  Neighbor nearest;
  CachedKnn(tree, points, query, 1, &cache, &nearest.index, &nearest.distance_squared);
  return nearest;
}

// The nearest of `points` to `query`, a point that was at `previous` when it last asked: through
// `cache` while it moves by less than half the cache's reach per question. A query still
// travelling farther (the first iterations from a large misalignment) would miss its cache and
// refill it, the M nearest, at every step; it asks the tree for the nearest alone instead and
// leaves its cache for when it slows down. The answer is the nearest either way (on an exact tie
// of distances the two paths may name different points).
template <int M>
Neighbor TravellingNearest(const KdTree& tree, const std::vector<Vec3>& points, const Vec3& query,
                           const Vec3& previous, NeighborCache<M>& cache) {
  if (cache.reach > 0.0 && (query - previous).squaredNorm() > 0.25 * cache.reach * cache.reach) {
    return tree.Nearest(query);
  }
  return CachedNearest(tree, points, query, cache);
}

}  // namespace mlsreg
