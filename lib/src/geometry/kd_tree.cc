#include "mlsreg/geometry/kd_tree.h"

#include <algorithm>
#include <mutex>
#include <nanoflann.hpp>

#include "mlsreg/core/parallel_for.h"

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

const nanoflann::KDTreeSingleIndexAdaptorParams kUnbuilt(
    kLeafSize, nanoflann::KDTreeSingleIndexAdaptorFlags::SkipInitialBuildIndex);

// Below this many points a tree builds on one thread (a few hundred microseconds).
constexpr std::size_t kMinPointsPerParallelBuild = 8192;

// nanoflann 1.4.3 builds a tree by recursion: split the range of points at the middle of its
// bounding box's widest side (`middleSplit_`, which permutes the range), then build the two
// halves, then tighten the node's bounds from theirs. The halves touch disjoint ranges of the
// permutation and nothing else of each other, so they can be built at once. What nanoflann does
// not allow is two builds allocating nodes from one tree's pool: each subtree below the top
// levels is built by a tree object of its own (its pool then holds those nodes for the tree's
// lifetime) over a copy of the permutation, whose range is copied back.
class ParallelBuild {
 public:
  using BoundingBox = NanoflannTree::BoundingBox;
  using NodePtr = NanoflannTree::NodePtr;
  using Offset = NanoflannTree::Offset;

  ParallelBuild(NanoflannTree& tree, const PointArrayAdaptor& adaptor,
                std::vector<std::unique_ptr<NanoflannTree>>& subtree_owners, int threads)
      : tree_(tree), adaptor_(adaptor), owners_(subtree_owners) {
    // Four subtrees per thread balance halves of unequal size (the split is at the middle of
    // the box, not at the median), at most 16.
    while ((std::size_t{1} << levels_) < std::min<std::size_t>(16, 4 * std::size_t(threads))) {
      ++levels_;
    }
  }

  // What NanoflannTree::buildIndex does, with the recursion below.
  void Run() {
    tree_.init_vind();
    tree_.freeIndex(tree_);
    tree_.m_size_at_index_build = tree_.m_size;
    if (tree_.m_size == 0) return;
    tree_.computeBoundingBox(tree_.root_bbox);
    owners_.resize(std::size_t{1} << levels_);
    tree_.root_node = Divide(0, tree_.m_size, tree_.root_bbox, levels_, 0);
  }

 private:
  // nanoflann's divideTree for the top `levels` levels, the two halves at once. `path` is the
  // node's place among those of its level (its turns from the root as bits).
  NodePtr Divide(Offset left, Offset right, BoundingBox& bbox, int levels, std::size_t path) {
    if (levels == 0 || right - left <= tree_.m_leaf_max_size) {
      return BuildSubtree(left, right, bbox, path << levels);  // a subtree owner of its own
    }
    NodePtr node;
    {
      const std::lock_guard lock(pool_mutex_);
      node = tree_.pool.template allocate<NanoflannTree::Node>();
    }
    Offset index = 0;
    int cut_dimension = 0;
    double cut_value = 0.0;
    tree_.middleSplit_(tree_, left, right - left, index, cut_dimension, cut_value, bbox);
    node->node_type.sub.divfeat = cut_dimension;
    BoundingBox left_bbox(bbox);
    left_bbox[cut_dimension].high = cut_value;
    BoundingBox right_bbox(bbox);
    right_bbox[cut_dimension].low = cut_value;
    internal::RunOnPool(2, [&](std::size_t half) {
      if (half == 0) {
        node->child1 = Divide(left, left + index, left_bbox, levels - 1, 2 * path);
      } else {
        node->child2 = Divide(left + index, right, right_bbox, levels - 1, 2 * path + 1);
      }
    });
    node->node_type.sub.divlow = left_bbox[cut_dimension].high;
    node->node_type.sub.divhigh = right_bbox[cut_dimension].low;
    for (int i = 0; i < 3; ++i) {
      bbox[i].low = std::min(left_bbox[i].low, right_bbox[i].low);
      bbox[i].high = std::max(left_bbox[i].high, right_bbox[i].high);
    }
    return node;
  }

  NodePtr BuildSubtree(Offset left, Offset right, BoundingBox& bbox, std::size_t subtree) {
    auto& owner = owners_[subtree];
    owner = std::make_unique<NanoflannTree>(3, adaptor_, kUnbuilt);
    owner->vAcc.resize(right);  // offsets are absolute: only [left, right) is read
    std::copy(tree_.vAcc.begin() + left, tree_.vAcc.begin() + right, owner->vAcc.begin() + left);
    const NodePtr node = owner->divideTree(*owner, left, right, bbox);
    std::copy(owner->vAcc.begin() + left, owner->vAcc.begin() + right, tree_.vAcc.begin() + left);
    owner->vAcc = {};
    return node;
  }

  NanoflannTree& tree_;
  const PointArrayAdaptor& adaptor_;
  std::vector<std::unique_ptr<NanoflannTree>>& owners_;
  int levels_ = 0;
  std::mutex pool_mutex_;
};

}  // namespace

struct KdTree::Impl {
  Impl(const std::vector<Vec3>& pts, int threads)
      : adaptor{pts.data(), pts.size()}, tree(3, adaptor, kUnbuilt) {
    if (threads <= 1 || pts.size() < kMinPointsPerParallelBuild) {
      tree.buildIndex();
    } else {
      ParallelBuild(tree, adaptor, subtree_owners, threads).Run();
    }
  }
  PointArrayAdaptor adaptor;
  mutable NanoflannTree tree;  // usedMemory() is not const in nanoflann 1.4.3
  // The pools holding the nodes of subtrees built on other threads (empty when built on one).
  std::vector<std::unique_ptr<NanoflannTree>> subtree_owners;
};

KdTree::KdTree(const std::vector<Vec3>& points, int threads)
    : impl_(std::make_unique<Impl>(points, threads)) {}
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

std::size_t KdTree::MemoryBytes() const {
  std::size_t bytes = impl_->tree.usedMemory(impl_->tree);
  for (const auto& owner : impl_->subtree_owners) {
    if (owner) bytes += owner->pool.usedMemory + owner->pool.wastedMemory;
  }
  return bytes;
}

}  // namespace mlsreg
