#include "mlsreg/kd_tree.h"

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
  impl_->tree.knnSearch(query.data(), 1, &n.index, &n.distance_squared);
  return n;
}

std::size_t KdTree::Knn(const Vec3& query, std::size_t k, std::uint32_t* indices,
                        double* distances_squared) const {
  return impl_->tree.knnSearch(query.data(), k, indices, distances_squared);
}

void KdTree::Radius(const Vec3& query, double radius, RadiusNeighbors& out) const {
  nanoflann::SearchParams params(32, 0.0f, /*sorted=*/false);
  impl_->tree.radiusSearch(query.data(), radius * radius, out, params);
}

std::size_t KdTree::MemoryBytes() const { return impl_->tree.usedMemory(impl_->tree); }

}  // namespace mlsreg
