#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "mlsreg/core/length.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/correspondences/correspondence_filter.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/neighbor_cache.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/surface_cache.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

struct FilterCase {
  Vec3 source_normal;
  double source_h;
  Correspondence c;
};

// Lengths as users write them: in units of d, or in the clouds' units read as metres.
TEST(LengthTest, ParsesUnitsOfDAndMetricLengths) {
  const auto parsed = [](std::string_view text) { return ParseLength(text, "--x").value(); };
  EXPECT_EQ(parsed("20").value, 20.0);
  EXPECT_FALSE(parsed("20").absolute);
  EXPECT_EQ(parsed("2.5d").value, 2.5);
  EXPECT_FALSE(parsed("2.5 d").absolute);
  EXPECT_EQ(parsed("5m").value, 5.0);
  EXPECT_TRUE(parsed("5m").absolute);
  EXPECT_DOUBLE_EQ(parsed("30cm").value, 0.3);
  EXPECT_DOUBLE_EQ(parsed("5 mm ").value, 0.005);
  EXPECT_TRUE(parsed("5mm").absolute);
  // In the clouds' units and in d, for a cloud with d = 2 cm.
  EXPECT_DOUBLE_EQ(parsed("5m").In(0.02), 5.0);
  EXPECT_DOUBLE_EQ(parsed("5m").InD(0.02), 250.0);
  EXPECT_DOUBLE_EQ(parsed("20").In(0.02), 0.4);
  EXPECT_DOUBLE_EQ(parsed("20").InD(0.02), 20.0);
  for (std::string_view bad : {"", "m", "5km", "five", "5 m m", "inf", "nan", "1e999m"}) {
    SCOPED_TRACE(bad);
    const auto status = ParseLength(bad, "--overlap-distance").status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(status.message().find("--overlap-distance: '"), 0u) << status.message();
  }
}

TEST(CorrespondenceFilterTest, RejectsEachReasonAndCountsIt) {
  Correspondence good{Vec3(0, 0, 0.1), Vec3::UnitZ(), 0.010, true};
  std::vector<Vec3> points(6, Vec3::Zero());
  std::vector<Vec3> normals(6, Vec3::UnitZ());
  std::vector<double> h(6, 0.010);
  std::vector<std::uint8_t> valid(6, 1);
  std::vector<Correspondence> c(6, good);
  c[1].valid = false;                              // invalid projection
  c[2].point = Vec3(0, 0, 10.0);                   // too far
  c[3].normal = Vec3(1, 0, 1).normalized() * 1.0;  // dot = 0.707 >= 0.7: kept
  c[4].normal = Vec3(1, 0, 0.9).normalized();      // dot = 0.669 < 0.7: rejected
  c[5].curvature = 0.020;                          // ratio 0.5 < 0.75: rejected
  CorrespondenceFilterOptions options;
  options.max_distance = 1.0;
  const CorrespondenceFilter filter(options);
  std::vector<std::uint8_t> accepted(6);
  const CorrespondenceCounts counts = filter.Apply(points, normals, h, valid, c, accepted);
  EXPECT_EQ(counts.matched, 2);
  EXPECT_EQ(counts.invalid, 1);
  EXPECT_EQ(counts.rejected_distance, 1);
  EXPECT_EQ(counts.rejected_normal, 1);
  EXPECT_EQ(counts.rejected_curvature, 1);
  EXPECT_EQ(counts.total(), 6);
  EXPECT_EQ(accepted, (std::vector<std::uint8_t>{1, 0, 0, 1, 0, 0}));
  // Each sample's fate, and the counts rebuilt from the fates.
  std::vector<PairFate> fates(6);
  filter.Apply(points, normals, h, valid, c, accepted, fates);
  EXPECT_EQ(fates, (std::vector<PairFate>{PairFate::kMatched, PairFate::kInvalid, PairFate::kTooFar,
                                          PairFate::kMatched, PairFate::kNormalsDisagree,
                                          PairFate::kCurvaturesDisagree}));
  CorrespondenceCounts rebuilt;
  for (PairFate fate : fates) rebuilt.Add(fate);
  rebuilt += rebuilt;
  EXPECT_EQ(rebuilt.matched, 4);
  EXPECT_EQ(rebuilt.invalid, 2);
  EXPECT_EQ(rebuilt.rejected_distance, 2);
  EXPECT_EQ(rebuilt.rejected_normal, 2);
  EXPECT_EQ(rebuilt.rejected_curvature, 2);
}

TEST(CorrespondenceFilterTest, NormalSignMattersOnlyWhenBothSidesAreOriented) {
  std::vector<Vec3> points{Vec3::Zero()}, normals{Vec3::UnitZ()};
  std::vector<double> h{0.01};
  std::vector<std::uint8_t> valid{1}, accepted(1);
  std::vector<Correspondence> c{{Vec3::Zero(), -Vec3::UnitZ(), 0.01, true}};
  CorrespondenceFilterOptions options;
  EXPECT_EQ(CorrespondenceFilter(options).Apply(points, normals, h, valid, c, accepted).matched, 1);
  options.source_oriented = options.target_oriented = true;
  EXPECT_EQ(
      CorrespondenceFilter(options).Apply(points, normals, h, valid, c, accepted).rejected_normal,
      1);
}

TEST(CorrespondenceFilterTest, CurvatureRatioIsSymmetricAndFloored) {
  std::vector<Vec3> points{Vec3::Zero()}, normals{Vec3::UnitZ()};
  std::vector<std::uint8_t> valid{1}, accepted(1);
  const CorrespondenceFilter filter{CorrespondenceFilterOptions{}};
  auto kept = [&](double h1, double h2) {
    std::vector<double> h{h1};
    std::vector<Correspondence> c{{Vec3::Zero(), Vec3::UnitZ(), h2, true}};
    return filter.Apply(points, normals, h, valid, c, accepted).matched == 1;
  };
  EXPECT_TRUE(kept(0.010, 0.0130));   // 0.77
  EXPECT_FALSE(kept(0.010, 0.0140));  // 0.71
  EXPECT_TRUE(kept(0.0130, 0.010));   // 1.3 <= 1/0.75
  EXPECT_FALSE(kept(0.0140, 0.010));  // 1.4 > 1/0.75
  EXPECT_TRUE(kept(1e-9, 1e-6));      // both flat: compared at the floor
}

TEST(SamplingTest, SamplingDistanceOfRegularGridIsItsSpacing) {
  const PointCloud grid = testing::SamplePlaneGrid(1.0, 0.05, 0.0, 1);
  const KdTree tree(grid.points);
  EXPECT_NEAR(SamplingDistance(grid.points, tree), 0.05, 1e-9);
}

TEST(SamplingTest, SamplingDistanceSkipsDuplicates) {
  std::vector<Vec3> points{Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 0, 0)};
  const KdTree tree(points);
  EXPECT_DOUBLE_EQ(SamplingDistance(points, tree), 1.0);
}

TEST(SamplingTest, RandomSubsampleIsSeededDistinctAndSorted) {
  const auto a = RandomSubsample(10000, 2000, 42);
  const auto b = RandomSubsample(10000, 2000, 42);
  const auto c = RandomSubsample(10000, 2000, 43);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  ASSERT_EQ(a.size(), 2000u);
  for (std::size_t i = 1; i < a.size(); ++i) EXPECT_LT(a[i - 1], a[i]);
  EXPECT_LT(a.back(), 10000u);
  EXPECT_EQ(RandomSubsample(5, 10, 1).size(), 5u);
}

// The cache answers every request with what AnalyzeSurface gives for it, bit for bit, and
// analyses each point once: a second request over a subset analyses nothing new, a request over
// every point only the rest; another radius starts over.
TEST(SurfaceCacheTest, AnswersAsTheAnalysisAndAnalysesEachPointOnce) {
  const PointCloud sphere = testing::SampleSphere(3000, 1.0, -0.5, 3);
  const KdTree tree(sphere.points);
  const double radius = 4.0 * SamplingDistance(sphere.points, tree);
  const std::optional<Vec3> viewpoint = Vec3(0.0, 0.0, 5.0);
  SurfaceCache cache(sphere.points, tree, viewpoint);
  const auto expect_as_analysed = [&](double r, const std::vector<std::uint32_t>& indices) {
    const SurfaceProperties want = AnalyzeSurface(sphere.points, tree, r, viewpoint, indices);
    const SurfaceProperties got = cache.At(r, indices, {}, 2);
    ASSERT_FALSE(got.stopped);
    EXPECT_EQ(got.oriented, want.oriented);
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t k = 0; k < want.size(); ++k) {
      EXPECT_EQ(got.normals[k], want.normals[k]) << k;
      EXPECT_EQ(got.curvature[k], want.curvature[k]) << k;
      EXPECT_EQ(got.valid[k], want.valid[k]) << k;
    }
  };
  const std::vector<std::uint32_t> some = RandomSubsample(sphere.size(), 500, 7);
  expect_as_analysed(radius, some);
  EXPECT_EQ(cache.analysed(), 500u);
  expect_as_analysed(radius, RandomSubsample(sphere.size(), 200, 7));  // a subset of `some`
  EXPECT_EQ(cache.analysed(), 500u);
  expect_as_analysed(radius, {});  // every point
  EXPECT_EQ(cache.analysed(), sphere.size());
  expect_as_analysed(2.0 * radius, some);
  EXPECT_EQ(cache.analysed(), 500u);
}

// Queries on random walks (steps of a tenth of the spacing, a jump across the cloud now and
// then): the cache's answers are the brute-force k nearest, and most come from the cache.
TEST(NeighborCacheTest, AnswersAreTheNearestAndMostComeFromTheCache) {
  const PointCloud cloud = testing::SampleBumpySurface(3000, -1, 1, 3);
  const KdTree tree(cloud.points);
  const double spacing = SamplingDistance(cloud.points, tree);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  int queries = 0, refills = 0;
  for (const int k : {1, 5}) {
    NeighborCache<8> cache;
    Vec3 q(0.0, 0.0, 0.0);
    for (int step = 0; step < 400; ++step, ++queries) {
      q += (step % 50 == 49 ? 0.5 : 0.1 * spacing) * Vec3(g(rng), g(rng), 0.2 * g(rng));
      q = q.cwiseMax(Vec3(-1, -1, -1)).cwiseMin(Vec3(1, 1, 1));
      const Vec3 before = cache.center;
      std::uint32_t index[5];
      double distance_squared[5];
      ASSERT_EQ(CachedKnn(tree, cloud.points, q, k, &cache, index, distance_squared),
                static_cast<std::size_t>(k));
      refills += cache.center != before;
      std::vector<std::pair<double, std::uint32_t>> brute;
      for (std::uint32_t i = 0; i < cloud.size(); ++i) {
        brute.push_back({(cloud.points[i] - q).squaredNorm(), i});
      }
      std::partial_sort(brute.begin(), brute.begin() + k, brute.end());
      for (int j = 0; j < k; ++j) {
        EXPECT_EQ(index[j], brute[j].second) << "k " << k << " step " << step << " j " << j;
        EXPECT_EQ(distance_squared[j], brute[j].first);
      }
      if (k == 1) {
        const Neighbor nearest = CachedNearest(tree, cloud.points, q, cache);
        EXPECT_EQ(nearest.index, brute[0].second);
      }
    }
  }
  EXPECT_LT(refills, queries / 3) << refills << " refills in " << queries << " queries";
}

// A query that jumps by more than half its cache's reach gets the tree's nearest without
// refilling the cache; once it creeps, the cache answers again. The answer is always the nearest.
TEST(NeighborCacheTest, ATravellingQueryAsksTheTreeAndLeavesItsCache) {
  const PointCloud cloud = testing::SampleBumpySurface(3000, -1, 1, 3);
  const KdTree tree(cloud.points);
  const double spacing = SamplingDistance(cloud.points, tree);
  const auto brute_nearest = [&](const Vec3& q) {
    std::uint32_t best = 0;
    for (std::uint32_t i = 1; i < cloud.size(); ++i) {
      if ((cloud.points[i] - q).squaredNorm() < (cloud.points[best] - q).squaredNorm()) best = i;
    }
    return best;
  };
  NeighborCache<8> cache;
  Vec3 previous(0.0, 0.0, 0.0), q = previous;
  EXPECT_EQ(TravellingNearest(tree, cloud.points, q, previous, cache).index, brute_nearest(q));
  ASSERT_GT(cache.reach, 0.0);  // the first question fills the cache
  const Vec3 filled_at = cache.center;
  // Travelling: steps of 20 spacings, far beyond the cache's reach.
  int travelled = 0;
  for (int step = 0; step < 8; ++step) {
    previous = q;
    q += Vec3(0.05, 0.04, 0.0);
    const Neighbor nearest = TravellingNearest(tree, cloud.points, q, previous, cache);
    EXPECT_EQ(nearest.index, brute_nearest(q)) << "step " << step;
    travelled += cache.center == filled_at;
  }
  EXPECT_EQ(travelled, 8) << "a travelling query refilled its cache";
  // Creeping: steps of a tenth of a spacing; the cache is refilled once, then answers.
  int refills = 0;
  for (int step = 0; step < 20; ++step) {
    previous = q;
    q += Vec3(0.1 * spacing, 0.0, 0.0);
    const Vec3 before = cache.center;
    EXPECT_EQ(TravellingNearest(tree, cloud.points, q, previous, cache).index, brute_nearest(q));
    refills += cache.center != before;
  }
  EXPECT_GE(refills, 1);
  EXPECT_LE(refills, 5);
}

TEST(TransformTest, ParsesRowMajorAndRejectsNonRigid) {
  auto ok = ParseTransform("0 -1 0 1, 1 0 0 2, 0 0 1 3, 0 0 0 1", "init");
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_DOUBLE_EQ((*ok)(0, 1), -1.0);
  EXPECT_DOUBLE_EQ((*ok)(1, 3), 2.0);
  auto scaled = ParseTransform("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "init");
  EXPECT_EQ(scaled.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(scaled.status().message().find("init is not rigid"), std::string::npos);
  auto reflection = ParseTransform("-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "gt");
  EXPECT_NE(reflection.status().message().find("reflection"), std::string::npos);
  auto short_list = ParseTransform("1 0 0", "init");
  EXPECT_NE(short_list.status().message().find("16 numbers"), std::string::npos);
  auto nan = ParseTransform("nan 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "init");
  EXPECT_EQ(nan.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(TransformTest, FormatRoundTripsExactly) {
  const Matrix4 m = RandomPerturbation(33.0, 0.7, Vec3(1, 2, 3), 9);
  auto parsed = ParseTransform(FormatTransform(m), "m");
  ASSERT_TRUE(parsed.ok());
  EXPECT_TRUE(parsed->isApprox(m, 1e-15));
}

TEST(TransformTest, PerturbationHasExactAngleAndOffsetAndIsSeeded) {
  const Vec3 center(0.3, -0.1, 2.0);
  const Matrix4 m = RandomPerturbation(10.0, 0.5, center, 77);
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  EXPECT_NEAR(Eigen::AngleAxisd(r).angle() * 180.0 / std::numbers::pi, 10.0, 1e-9);
  // The centre moves by exactly the translation.
  EXPECT_NEAR((r * center + m.topRightCorner<3, 1>() - center).norm(), 0.5, 1e-12);
  EXPECT_TRUE(m.isApprox(RandomPerturbation(10.0, 0.5, center, 77)));
  EXPECT_FALSE(m.isApprox(RandomPerturbation(10.0, 0.5, center, 78)));
}

// The RMS distance between two poses of the same points: a pure offset is its length; a turn
// by 90 degrees about z moves the unit points (1,0,0) and (0,1,0) by sqrt(2) each.
TEST(TransformTest, RmsDistanceBetweenPosesOfTheSamePoints) {
  const std::vector<Vec3> points = {Vec3(1, 0, 0), Vec3(0, 1, 0)};
  Matrix4 shifted = Matrix4::Identity();
  shifted.topRightCorner<3, 1>() = Vec3(0.3, 0.0, 0.4);
  EXPECT_NEAR(RmsDistanceBetween(points, Matrix4::Identity(), shifted), 0.5, 1e-12);
  Matrix4 turned = Matrix4::Identity();
  turned.topLeftCorner<3, 3>() << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_NEAR(RmsDistanceBetween(points, Matrix4::Identity(), turned), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(RmsDistanceBetween(points, shifted, shifted), 0.0, 1e-15);
  EXPECT_EQ(RmsDistanceBetween({}, Matrix4::Identity(), shifted), 0.0);
}

TEST(MetricsTest, RmseOfPureTranslationIsItsLength) {
  std::vector<Vec3> points{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 5, 0)};
  Matrix4 truth = Matrix4::Identity();
  Matrix4 estimate = Matrix4::Identity();
  estimate(0, 3) = 0.3;
  estimate(1, 3) = 0.4;
  const PoseError e = EvaluatePose(points, estimate, truth, 0.1);
  EXPECT_NEAR(e.rmse_d, 5.0, 1e-12);
  EXPECT_FALSE(e.success);  // 5 d is not < 5 d
  EXPECT_NEAR(e.translation_d, 5.0, 1e-12);
  EXPECT_NEAR(e.rotation_deg, 0.0, 1e-9);
  const PoseError rotated =
      EvaluatePose(points, RandomPerturbation(3.0, 0.0, Vec3::Zero(), 1), truth, 1.0);
  EXPECT_NEAR(rotated.rotation_deg, 3.0, 1e-9);
}

// The rotation error is resolved at every angle: a pose against itself is exactly 0, a turn of
// 1e-7 degrees reads as such (the arc cosine of the trace alone gives 0 or about 1e-6 there),
// and so do 90 and 179 degrees.
TEST(MetricsTest, RotationErrorIsResolvedFromZeroToAHalfTurn) {
  const std::vector<Vec3> points{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 5, 0)};
  for (int seed = 1; seed <= 5; ++seed) {
    const Matrix4 pose = RandomPerturbation(30.0, 2.0, Vec3(1, 2, 3), seed) *
                         RandomPerturbation(40.0, 1.0, Vec3::Zero(), 10 + seed);
    EXPECT_EQ(EvaluatePose(points, pose, pose, 1.0).rotation_deg, 0.0) << seed;
    for (const double degrees : {1e-7, 1e-3, 90.0, 179.0}) {
      const Matrix4 turned = RandomPerturbation(degrees, 0.0, Vec3::Zero(), seed) * pose;
      EXPECT_NEAR(EvaluatePose(points, turned, pose, 1.0).rotation_deg, degrees,
                  1e-9 + 1e-9 * degrees)
          << seed << ", " << degrees << " degrees";
    }
  }
}

}  // namespace
}  // namespace mlsreg
