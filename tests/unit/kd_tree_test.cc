// KdTree: its answers, and its tree, which is nanoflann's own for any thread count.
#include "mlsreg/geometry/kd_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>
#include <random>
#include <vector>

#include "support/synthetic.h"

namespace mlsreg {
namespace {

TEST(KdTreeTest, MatchesBruteForce) {
  const PointCloud cloud = testing::SampleBumpySurface(3000, -1, 1, 3);
  const KdTree tree(cloud.points);
  const Vec3 q(0.1, -0.2, 0.05);
  std::size_t best = 0;
  for (std::size_t i = 1; i < cloud.size(); ++i) {
    if ((cloud.points[i] - q).norm() < (cloud.points[best] - q).norm()) best = i;
  }
  EXPECT_EQ(tree.Nearest(q).index, best);
  RadiusNeighbors found;
  tree.Radius(q, 0.2, found);
  std::size_t brute = 0;
  for (const Vec3& p : cloud.points) brute += (p - q).norm() < 0.2;
  EXPECT_EQ(found.size(), brute);
}

// nanoflann 1.4.3 over the same points, built by its own buildIndex with KdTree's leaf size.
struct Points {
  const std::vector<Vec3>* points;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  double kdtree_get_pt(std::size_t i, std::size_t dim) const { return (*points)[i][dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using Nanoflann = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Points>,
                                                      Points, 3, std::uint32_t>;
constexpr std::size_t kLeafSize = 10;  // KdTree's

// Clouds that exercise every branch of the split: a bumpy surface, a cluster of 5,000 copies of
// one point, rings as dense as a LiDAR scan's near the sensor, a grid whose cuts fall on rows of
// points (ties with the cut value), points along one line (boxes of no width) and a cloud of one
// point repeated (a box of no extent).
std::vector<std::vector<Vec3>> SplitTestClouds() {
  std::vector<Vec3> mixed = testing::SampleBumpySurface(30'000, -1, 1, 3).points;
  for (int i = 0; i < 5'000; ++i) mixed.push_back(Vec3(0.25, 0.25, 0.1));
  for (int i = 0; i < 20'000; ++i) {
    const double r = 0.02 * (1 + i % 50), a = 0.001 * i;
    mixed.push_back(Vec3(r * std::cos(a), r * std::sin(a), -0.5));
  }
  std::vector<Vec3> grid;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      for (int k = 0; k < 8; ++k) grid.push_back(Vec3(0.05 * i - 1, 0.05 * j - 1, 0.1 * k));
    }
  }
  std::vector<Vec3> line;
  for (int i = 0; i < 9'000; ++i) line.push_back(Vec3(0.0002 * (i % 4000) - 0.4, 0.3, 0.0));
  const std::vector<Vec3> one_point(9'000, Vec3(0.1, 0.2, 0.3));
  return {mixed, grid, line, one_point};
}

// Every radius query returns the same neighbours in the same (search) order as nanoflann's own
// tree, and every k-nearest query the same list: the trees are the same node for node. Its
// memory is nanoflann's within a pool block per subtree.
TEST(KdTreeTest, IsNanoflannsOwnTreeForAnyThreadCount) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.1, 1.1);
  for (const std::vector<Vec3>& points : SplitTestClouds()) {
    const Points adaptor{&points};
    Nanoflann reference(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafSize));
    std::vector<Vec3> queries(300);
    for (Vec3& q : queries) q = Vec3(u(rng), u(rng), 0.6 * u(rng));
    for (int i = 0; i < 100; ++i) queries.push_back(points[(i * 547) % points.size()]);
    for (const int threads : {1, 2, 3, 8}) {
      const KdTree tree(points, threads);
      ASSERT_EQ(tree.size(), points.size());
      EXPECT_NEAR(static_cast<double>(tree.MemoryBytes()),
                  static_cast<double>(reference.usedMemory(reference)), 16 * 8192);
      for (const Vec3& q : queries) {
        std::vector<std::pair<std::uint32_t, double>> want;
        nanoflann::RadiusResultSet<double, std::uint32_t> radius_set(0.15 * 0.15, want);
        reference.findNeighbors(radius_set, q.data(), nanoflann::SearchParams(32, 0.0f, false));
        RadiusNeighbors got;
        tree.Radius(q, 0.15, got, points.size());
        if (want.size() < points.size()) {
          ASSERT_EQ(got, want) << "threads " << threads << " query " << q.transpose();
        }
        std::uint32_t want_index[12], got_index[12];
        double want_distance[12], got_distance[12];
        nanoflann::KNNResultSet<double, std::uint32_t> knn_set(12);
        knn_set.init(want_index, want_distance);
        reference.findNeighbors(knn_set, q.data(), nanoflann::SearchParams());
        ASSERT_EQ(tree.Knn(q, 12, got_index, got_distance), knn_set.size());
        for (std::size_t j = 0; j < knn_set.size(); ++j) {
          EXPECT_EQ(got_distance[j], want_distance[j]) << "threads " << threads;
          // Among exact duplicates, KdTree stops at the first k (both lists hold k of them).
          if (want_distance[j] > 0.0) {
            EXPECT_EQ(got_index[j], want_index[j]);
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace mlsreg
