#include "mlsreg/geometry/kd_tree.h"

#include <algorithm>
#include <mutex>
#include <nanoflann.hpp>
#include <tuple>

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

// The tree nanoflann 1.4.3 builds (`buildIndex`), node for node, built faster and on threads.
// nanoflann builds by recursion: split the range of points at the middle of its bounding box's
// widest side (`middleSplit_`, which permutes the range), then build the two halves, then tighten
// the node's bounds from theirs. Each split reads the range's coordinates up to four times, every
// one through the permutation, and finds their range in one chain of comparisons that waits on
// each before the next. Here the permutation carries each point's coordinates beside its index,
// so each pass reads memory in order, and the range is found in four independent chains. Every
// decision and every swap is nanoflann's, so the nodes, bounds and permutation are its own
// (KdTreeTest.IsNanoflannsOwnTreeForAnyThreadCount); the build takes two thirds of the time.
// The halves touch disjoint ranges of the permutation and nothing else of each other, so the top
// levels build their halves at once; each subtree below them allocates its nodes from a pool of
// its own (nanoflann's pool is not thread-safe), kept for the tree's lifetime.
class TreeBuild {
 public:
  using BoundingBox = NanoflannTree::BoundingBox;
  using NodePtr = NanoflannTree::NodePtr;
  using Node = NanoflannTree::Node;
  using Offset = NanoflannTree::Offset;
  using Pool = nanoflann::PooledAllocator;

  TreeBuild(NanoflannTree& tree, const PointArrayAdaptor& adaptor,
            std::vector<std::unique_ptr<Pool>>& subtree_pools, int threads)
      : tree_(tree), subtree_pools_(subtree_pools) {
    if (threads > 1 && adaptor.count >= kMinPointsPerParallelBuild) {
      // Four subtrees per thread balance halves of unequal size (the split is at the middle of
      // the box, not at the median), at most 16.
      while ((std::size_t{1} << levels_) < std::min<std::size_t>(16, 4 * std::size_t(threads))) {
        ++levels_;
      }
    }
    entries_.resize(adaptor.count);
    for (std::size_t i = 0; i < adaptor.count; ++i) {
      const Vec3& p = adaptor.points[i];
      entries_[i] = {{p.x(), p.y(), p.z()}, static_cast<std::uint32_t>(i)};
    }
  }

  // What NanoflannTree::buildIndex does.
  void Run() {
    tree_.init_vind();
    tree_.freeIndex(tree_);
    tree_.m_size_at_index_build = tree_.m_size;
    if (tree_.m_size == 0) return;
    tree_.computeBoundingBox(tree_.root_bbox);
    subtree_pools_.resize(levels_ == 0 ? 0 : std::size_t{1} << levels_);
    tree_.root_node = DivideTop(0, tree_.m_size, tree_.root_bbox, levels_, 0);
    for (std::size_t i = 0; i < entries_.size(); ++i) tree_.vAcc[i] = entries_[i].index;
  }

 private:
  // A point of the permutation with its coordinates.
  struct Entry {
    double coordinate[3];
    std::uint32_t index;
  };

  // The top `levels` levels, the two halves at once; below them a subtree with its own pool.
  // `path` is the node's place among those of its level (its turns from the root as bits).
  NodePtr DivideTop(Offset left, Offset right, BoundingBox& bbox, int levels, std::size_t path) {
    if (levels_ == 0) return Divide(left, right, bbox, tree_.pool);
    if (levels == 0 || right - left <= tree_.m_leaf_max_size) {
      auto& pool = subtree_pools_[path << levels];
      pool = std::make_unique<Pool>();
      return Divide(left, right, bbox, *pool);
    }
    NodePtr node;
    {
      const std::lock_guard lock(pool_mutex_);
      node = tree_.pool.template allocate<Node>();
    }
    const Split split = MiddleSplit(left, right - left, bbox);
    BoundingBox left_bbox(bbox), right_bbox(bbox);
    left_bbox[split.dimension].high = split.value;
    right_bbox[split.dimension].low = split.value;
    internal::RunOnPool(2, [&](std::size_t half) {
      if (half == 0) {
        node->child1 = DivideTop(left, left + split.index, left_bbox, levels - 1, 2 * path);
      } else {
        node->child2 = DivideTop(left + split.index, right, right_bbox, levels - 1, 2 * path + 1);
      }
    });
    Join(*node, split.dimension, left_bbox, right_bbox, bbox);
    return node;
  }

  // nanoflann's divideTree over entries [left, right), its nodes from `pool`.
  NodePtr Divide(Offset left, Offset right, BoundingBox& bbox, Pool& pool) {
    NodePtr node = pool.template allocate<Node>();
    if (right - left <= tree_.m_leaf_max_size) {
      node->child1 = node->child2 = nullptr;
      node->node_type.lr.left = left;
      node->node_type.lr.right = right;
      for (int i = 0; i < 3; ++i) {
        bbox[i].low = bbox[i].high = entries_[left].coordinate[i];
      }
      for (Offset k = left + 1; k < right; ++k) {
        for (int i = 0; i < 3; ++i) {
          const double value = entries_[k].coordinate[i];
          if (bbox[i].low > value) bbox[i].low = value;
          if (bbox[i].high < value) bbox[i].high = value;
        }
      }
      return node;
    }
    const Split split = MiddleSplit(left, right - left, bbox);
    BoundingBox left_bbox(bbox), right_bbox(bbox);
    left_bbox[split.dimension].high = split.value;
    node->child1 = Divide(left, left + split.index, left_bbox, pool);
    right_bbox[split.dimension].low = split.value;
    node->child2 = Divide(left + split.index, right, right_bbox, pool);
    Join(*node, split.dimension, left_bbox, right_bbox, bbox);
    return node;
  }

  // An inner node's bounds from its halves', as divideTree sets them.
  static void Join(Node& node, int dimension, const BoundingBox& left_bbox,
                   const BoundingBox& right_bbox, BoundingBox& bbox) {
    node.node_type.sub.divfeat = dimension;
    node.node_type.sub.divlow = left_bbox[dimension].high;
    node.node_type.sub.divhigh = right_bbox[dimension].low;
    for (int i = 0; i < 3; ++i) {
      bbox[i].low = std::min(left_bbox[i].low, right_bbox[i].low);
      bbox[i].high = std::max(left_bbox[i].high, right_bbox[i].high);
    }
  }

  struct Split {
    Offset index = 0;  // the first entry of the upper half, relative to the range
    int dimension = 0;
    double value = 0.0;
  };

  // nanoflann's middleSplit_: the widest side of the box among those the points spread over
  // most, cut at its middle clamped to the points' range, then planeSplit's partition.
  Split MiddleSplit(Offset first, Offset count, const BoundingBox& bbox) {
    constexpr double kEps = 0.00001;
    double max_span = bbox[0].high - bbox[0].low;
    for (int i = 1; i < 3; ++i) max_span = std::max(max_span, bbox[i].high - bbox[i].low);
    Split split;
    double max_spread = -1.0;
    double cut_min = 0.0, cut_max = 0.0;
    for (int i = 0; i < 3; ++i) {
      if (bbox[i].high - bbox[i].low > (1 - kEps) * max_span) {
        const auto [min_value, max_value] = MinMax(first, count, i);
        if (max_value - min_value > max_spread) {
          split.dimension = i;
          max_spread = max_value - min_value;
          cut_min = min_value;
          cut_max = max_value;
        }
      }
    }
    if (max_spread < 0.0) {  // a box of no extent: nanoflann cuts dimension 0
      std::tie(cut_min, cut_max) = MinMax(first, count, 0);
    }
    const double middle = (bbox[split.dimension].low + bbox[split.dimension].high) / 2;
    split.value = std::clamp(middle, cut_min, cut_max);
    const auto [lim1, lim2] = PlaneSplit(first, count, split.dimension, split.value);
    if (lim1 > count / 2) {
      split.index = lim1;
    } else if (lim2 < count / 2) {
      split.index = lim2;
    } else {
      split.index = count / 2;
    }
    return split;
  }

  // The range of the entries' coordinates along `dimension`, in four independent running
  // minima and maxima (one chain would wait on each comparison before the next).
  std::pair<double, double> MinMax(Offset first, Offset count, int dimension) const {
    const Entry* e = entries_.data() + first;
    double low[4], high[4];
    for (int j = 0; j < 4; ++j) low[j] = high[j] = e[0].coordinate[dimension];
    Offset i = 0;
    for (; i + 4 <= count; i += 4) {
      for (int j = 0; j < 4; ++j) {
        low[j] = std::min(low[j], e[i + j].coordinate[dimension]);
        high[j] = std::max(high[j], e[i + j].coordinate[dimension]);
      }
    }
    for (; i < count; ++i) {
      low[0] = std::min(low[0], e[i].coordinate[dimension]);
      high[0] = std::max(high[0], e[i].coordinate[dimension]);
    }
    return {std::min(std::min(low[0], low[1]), std::min(low[2], low[3])),
            std::max(std::max(high[0], high[1]), std::max(high[2], high[3]))};
  }

  // nanoflann's planeSplit, step for step: entries below `cut` first, then those equal to it.
  std::pair<Offset, Offset> PlaneSplit(Offset first, Offset count, int dimension, double cut) {
    const Offset lim1 =
        SwapLoop(first, 0, count, dimension, [cut](double value) { return value < cut; });
    const Offset lim2 =
        SwapLoop(first, lim1, count, dimension, [cut](double value) { return value <= cut; });
    return {lim1, lim2};
  }

  // One of planeSplit's loops over entries [first + left, first + count): scans from the left
  // for an entry that does not go left and from the right for one that does, and swaps them
  // until the scans cross. Returns where the left scan stopped (relative to `first`).
  template <typename GoesLeft>
  Offset SwapLoop(Offset first, Offset left, Offset count, int dimension,
                  const GoesLeft& goes_left) {
    Entry* e = entries_.data() + first;
    const auto at = [&](Offset i) { return e[i].coordinate[dimension]; };
    Offset right = count - 1;
    for (;;) {
      while (left <= right && goes_left(at(left))) ++left;
      while (right && left <= right && !goes_left(at(right))) --right;
      if (left > right || !right) break;  // "!right": nanoflann's guard for unsigned offsets
      std::swap(e[left], e[right]);
      ++left;
      --right;
    }
    return left;
  }

  NanoflannTree& tree_;
  std::vector<std::unique_ptr<Pool>>& subtree_pools_;
  std::vector<Entry> entries_;
  int levels_ = 0;
  std::mutex pool_mutex_;
};

}  // namespace

struct KdTree::Impl {
  Impl(const std::vector<Vec3>& pts, int threads)
      : adaptor{pts.data(), pts.size()}, tree(3, adaptor, kUnbuilt) {
    TreeBuild(tree, adaptor, subtree_pools, threads).Run();
  }
  PointArrayAdaptor adaptor;
  mutable NanoflannTree tree;  // usedMemory() is not const in nanoflann 1.4.3
  // The pools holding the nodes of subtrees built on other threads (empty when built on one).
  std::vector<std::unique_ptr<nanoflann::PooledAllocator>> subtree_pools;
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
  for (const auto& pool : impl_->subtree_pools) {
    if (pool) bytes += pool->usedMemory + pool->wastedMemory;
  }
  return bytes;
}

}  // namespace mlsreg
