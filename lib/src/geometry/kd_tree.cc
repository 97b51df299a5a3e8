#include "mlsreg/geometry/kd_tree.h"

#include <algorithm>
#include <nanoflann.hpp>

namespace mlsreg {
namespace {

// nanoflann dataset adaptor over a contiguous array of Vec3.
struct PointArrayAdaptor {
  const Vec3* points = nullptr;
  std::size_t count = 0;

  std::size_t kdtree_get_point_count() const { return count; }
  double kdtree_get_pt(std::size_t index, std::size_t dim) const { return points[index][dim]; }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox&) const {
    return false;
  }
};

using NanoflannTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointArrayAdaptor>,
                                        PointArrayAdaptor, 3, std::uint32_t>;
constexpr std::size_t kLeafSize = 10;

// nanoflann keeps descending into every cell whose distance is <= the current worst distance,
// so once a result set is full of exact duplicates (worst distance 0) the plain sets still visit
// every other duplicate: n queries into a cluster of n identical points cost n^2. Both sets
// below end the search there, since nothing can come closer than 0.

// k nearest (sorted), stopping at k exact duplicates.
class NearestK : public nanoflann::KNNResultSet<double, std::uint32_t> {
 public:
  using KNNResultSet::KNNResultSet;
  bool addPoint(double dist, std::uint32_t index) {
    KNNResultSet::addPoint(dist, index);
    return !(full() && worstDist() <= 0.0);
  }
};

// The nearest `capacity` points closer than the radius: appended in search order while fewer
// are found (the same output as nanoflann's radius search), kept as a max-heap by distance once
// full, so a query into a dense cluster costs O(log capacity) per extra point.
class NearestWithinRadius {
 public:
  NearestWithinRadius(double radius_squared, std::size_t capacity, RadiusNeighbors& out)
      : radius_squared_(radius_squared), capacity_(std::max<std::size_t>(1, capacity)), out_(out) {
    out_.clear();
  }
  std::size_t size() const { return out_.size(); }
  bool full() const { return out_.size() >= capacity_; }
  double worstDist() const { return full() ? out_.front().second : radius_squared_; }

  // nanoflann calls this only for dist < worstDist(); false ends the search.
  bool addPoint(double dist, std::uint32_t index) {
    if (!full()) {
      out_.emplace_back(index, dist);
      if (full()) std::make_heap(out_.begin(), out_.end(), FartherFirst);
    } else {
      std::pop_heap(out_.begin(), out_.end(), FartherFirst);
      out_.back() = {index, dist};
      std::push_heap(out_.begin(), out_.end(), FartherFirst);
    }
    return !(full() && out_.front().second <= 0.0);
  }

 private:
  static bool FartherFirst(const std::pair<std::uint32_t, double>& a,
                           const std::pair<std::uint32_t, double>& b) {
    return a.second < b.second;
  }
  double radius_squared_;
  std::size_t capacity_;
  RadiusNeighbors& out_;
};

}  // namespace

struct KdTree::Impl {
  explicit Impl(const std::vector<Vec3>& pts)
      : adaptor{pts.data(), pts.size()},
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize)) {}  // builds
  PointArrayAdaptor adaptor;
  mutable NanoflannTree tree;  // usedMemory() is not const in nanoflann 1.4.3
};

KdTree::KdTree(const std::vector<Vec3>& points) : impl_(std::make_unique<Impl>(points)) {}
KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

std::size_t KdTree::size() const { return impl_->adaptor.count; }

Neighbor KdTree::Nearest(const Vec3& query) const {
  Neighbor n;
  Knn(query, 1, &n.index, &n.distance_squared);
  return n;
}

std::size_t KdTree::Knn(const Vec3& query, std::size_t k, std::uint32_t* indices,
                        double* distances_squared) const {
  NearestK result(k);
  result.init(indices, distances_squared);
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  return result.size();
}

void KdTree::Radius(const Vec3& query, double radius, RadiusNeighbors& out,
                    std::size_t max_neighbors) const {
  NearestWithinRadius result(radius * radius, max_neighbors, out);
  if (size() == 0) return;
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams(32, 0.0f, false));
}

std::size_t KdTree::MemoryBytes() const { return impl_->tree.usedMemory(impl_->tree); }

}  // namespace mlsreg
