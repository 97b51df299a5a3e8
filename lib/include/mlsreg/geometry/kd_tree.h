// KdTree: nearest-neighbour, k-nearest and radius queries over a fixed set of 3-D points.
#pragma once

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

// One neighbour found by a query: its index in the indexed point set and its squared distance.
struct Neighbor {
  std::uint32_t index = 0;
  double distance_squared = 0.0;
};

// Reusable output buffer of radius queries; keep one per thread so queries do not allocate once
// it has grown to the neighbourhood size.
using RadiusNeighbors = std::vector<std::pair<std::uint32_t, double>>;

// The most neighbours a radius query returns: the nearest ones win. It bounds the work and
// memory of every neighbourhood computation by a constant, however dense a cloud is (a cluster
// of identical points would otherwise make one query return the whole cloud). At the radii the
// methods use (5-20 d: 20-1300 neighbours) it is never reached.
inline constexpr std::size_t kMaxRadiusNeighbors = 4096;

// A kd-tree (nanoflann) over points owned by someone else. The points must outlive the tree and
// must not be modified; moving the owning std::vector is fine (its buffer does not move).
class KdTree {
 public:
  // Builds the tree on up to `threads` threads (the pool of ParallelFor). The tree is the same
  // node for node for any thread count, so every query answers the same, in the same order: the
  // top levels are split as nanoflann splits them, and the subtrees below are built at once.
  explicit KdTree(const std::vector<Vec3>& points, int threads = 1);
  ~KdTree();
  KdTree(KdTree&&) noexcept;
  KdTree& operator=(KdTree&&) noexcept;
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  std::size_t size() const;

  // The closest indexed point to `query`. Requires a non-empty tree.
  Neighbor Nearest(const Vec3& query) const;

  // Up to k closest points, sorted by distance; returns how many were written. Among exact
  // duplicates of the query (distance 0) any k may be returned.
  std::size_t Knn(const Vec3& query, std::size_t k, std::uint32_t* indices,
                  double* distances_squared) const;

  // The points strictly closer than `radius`, at most `max_neighbors` of them (the nearest),
  // unsorted. `out` is cleared first. The search stops early once it holds `max_neighbors`
  // exact duplicates of the query, so its cost is bounded in dense clusters too.
  void Radius(const Vec3& query, double radius, RadiusNeighbors& out,
              std::size_t max_neighbors = kMaxRadiusNeighbors) const;

  // Approximate heap bytes used by the index (not the points).
  std::size_t MemoryBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mlsreg
