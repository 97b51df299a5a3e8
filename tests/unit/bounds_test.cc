// The bounds that keep one request's work and memory proportional to its parameters: capped
// neighbourhoods, searches that stop in clusters of duplicates, depth images capped by the
// point count, coordinates that cannot overflow, content digests, and loops that stop when
// asked.
#include <gtest/gtest.h>

#include <atomic>

#include "mlsreg/core/cloud_digest.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/geometry/fpfh.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/surface_analysis.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/io/intrinsics_sidecar.h"
#include "mlsreg/registration/registration.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

std::vector<Vec3> Cluster(std::size_t duplicates) {
  std::vector<Vec3> points(duplicates, Vec3(0.5, 0.5, 0.5));
  points.push_back(Vec3(1, 0, 0));
  points.push_back(Vec3(0, 1, 0));
  return points;
}

TEST(KdTreeBoundsTest, RadiusQueriesReturnTheNearestUpToTheCap) {
  const PointCloud surface = testing::SampleBumpySurface(5000, -1, 1, 3);
  const KdTree tree(surface.points);
  const Vec3 query = surface.points[17];
  RadiusNeighbors all, capped;
  tree.Radius(query, 0.5, all, /*max_neighbors=*/1'000'000);
  tree.Radius(query, 0.5, capped, /*max_neighbors=*/50);
  ASSERT_GT(all.size(), 50u);
  ASSERT_EQ(capped.size(), 50u);
  // The capped set is exactly the 50 nearest of the full one.
  std::sort(all.begin(), all.end(), [](auto& a, auto& b) { return a.second < b.second; });
  std::sort(capped.begin(), capped.end(), [](auto& a, auto& b) { return a.second < b.second; });
  for (std::size_t i = 0; i < capped.size(); ++i) EXPECT_EQ(capped[i].second, all[i].second);
  // Below the cap the result is the plain radius search (same set, same search order).
  RadiusNeighbors small;
  tree.Radius(query, 0.05, small);
  for (const auto& [index, d2] : small) EXPECT_LT(d2, 0.05 * 0.05);
  EXPECT_LT(small.size(), kMaxRadiusNeighbors);
}

TEST(KdTreeBoundsTest, QueriesIntoAClusterOfDuplicatesAreBounded) {
  const std::vector<Vec3> points = Cluster(40'000);
  const KdTree tree(points);
  RadiusNeighbors neighbors;
  tree.Radius(points[0], 10.0, neighbors);
  EXPECT_EQ(neighbors.size(), kMaxRadiusNeighbors);
  for (const auto& [index, d2] : neighbors) EXPECT_EQ(d2, 0.0);
  std::uint32_t indices[4];
  double d2[4];
  ASSERT_EQ(tree.Knn(points[0], 4, indices, d2), 4u);
  for (double d : d2) EXPECT_EQ(d, 0.0);
  EXPECT_EQ(tree.Nearest(Vec3(1, 0, 0.1)).index, 40'000u);
}

TEST(KdTreeBoundsTest, ATargetOfDuplicatesBuildsAndItsAnalysisStopsWhenAsked) {
  PointCloud cloud;
  cloud.points = Cluster(40'000);
  auto target = Target::Build(cloud);
  ASSERT_TRUE(target.ok()) << target.status();
  std::atomic<int> asked{0};
  auto stopped = Target::Build(cloud, {}, [&] { return ++asked > 2; });
  EXPECT_EQ(stopped.status().code(), absl::StatusCode::kCancelled);
  EXPECT_LE(asked.load(), 4);
}

TEST(FpfhBoundsTest, FeaturesUseAtMostTheCappedNeighbourhoodAndStopWhenAsked) {
  const PointCloud surface = testing::SampleBumpySurface(3000, -1, 1, 4);
  const KdTree tree(surface.points);
  const SurfaceProperties normals = AnalyzeSurface(surface.points, tree, 0.1, std::nullopt);
  // A radius that takes in the whole cloud: each feature still sees only the nearest 512.
  const std::vector<FpfhFeature> features =
      ComputeFpfh(surface.points, normals.normals, tree, 100.0);
  ASSERT_EQ(features.size(), surface.size());
  for (int block = 0; block < 3; ++block) {
    float sum = 0.0f;
    for (int b = 0; b < 11; ++b) sum += features[0][block * 11 + b];
    EXPECT_NEAR(sum, 100.0f, 0.01f);
  }
  EXPECT_TRUE(
      ComputeFpfh(surface.points, normals.normals, tree, 100.0, [] { return true; }).empty());
  // On several threads: the same features, bit for bit, and a stop asked from any thread.
  for (int threads : {2, 3}) {
    const std::vector<FpfhFeature> threaded =
        ComputeFpfh(surface.points, normals.normals, tree, 100.0, {}, threads);
    ASSERT_EQ(threaded.size(), features.size());
    for (std::size_t i = 0; i < features.size(); ++i) ASSERT_EQ(threaded[i], features[i]) << i;
    std::atomic<int> asked{0};
    EXPECT_TRUE(ComputeFpfh(surface.points, normals.normals, tree, 100.0,
                            [&] { return ++asked > 1; }, threads)
                    .empty());
  }
}

TEST(DepthGridBoundsTest, TheImageIsCappedByThePointCount) {
  EXPECT_EQ(MaxGridPixels(16), kMinGridPixelCap);
  EXPECT_EQ(MaxGridPixels(100'000), 6'400'000u);
  const PinholeIntrinsics huge{100000, 100000, 500, 500, 50000, 50000};
  const absl::Status s = ValidateIntrinsicsFor(huge, 16, "cloud.intrinsics");
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("cloud.intrinsics: a 100000 x 100000 image"), std::string::npos) << s;
  EXPECT_EQ(GridBytes(huge), std::uint64_t{40'000'000'000});
  std::vector<Vec3> points(16, Vec3(0, 0, 1));
  EXPECT_EQ(DepthGrid::Build(points, huge).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(ValidateIntrinsicsFor({640, 480, 525, 525, 320, 240}, 10'000, "k").ok());
}

TEST(DepthGridBoundsTest, SidecarSizesMustBeWholeNumbersInRange) {
  EXPECT_TRUE(ParseIntrinsics("320 240 300 300 160 120", "s").ok());
  for (const char* bad : {"1e300 240 300 300 160 120", "320.5 240 300 300 160 120",
                          "-1 240 300 300 160 120", "320 240 300 300 160", "1 2 3 4 5 6 7"}) {
    EXPECT_EQ(ParseIntrinsics(bad, "s").status().code(), absl::StatusCode::kInvalidArgument) << bad;
  }
}

TEST(CoordinateRangeTest, HugeCoordinatesAreRefusedNamingTheCause) {
  PointCloud cloud = testing::SampleBumpySurface(100, -1, 1, 5);
  EXPECT_TRUE(CheckCoordinateRange(cloud).ok());
  cloud.points[3] = Vec3(0, -1e200, 0);
  const absl::Status s = CheckCoordinateRange(cloud);
  EXPECT_NE(s.message().find("point 3 has a coordinate of magnitude 1e+200"), std::string::npos)
      << s;
  EXPECT_NE(Target::Build(cloud).status().message().find("magnitude"), std::string::npos);
}

TEST(CloudDigestTest, EqualNumbersGiveEqualDigestsAndAnyChangeAnother) {
  const PointCloud a = testing::SampleBumpySurface(500, -1, 1, 6);
  const std::string digest = CloudDigest(a);
  EXPECT_EQ(digest.rfind("sha256:", 0), 0u);
  EXPECT_EQ(digest.size(), 7u + 64u);
  EXPECT_EQ(CloudDigest(a), digest);
  PointCloud b = a;
  b.points[250].x() = std::nextafter(b.points[250].x(), 2.0);  // one ulp
  EXPECT_NE(CloudDigest(b), digest);
  PointCloud c = a;
  c.intrinsics = PinholeIntrinsics{64, 48, 50, 50, 32, 24};
  EXPECT_NE(CloudDigest(c), digest);
  PointCloud d = a;
  std::swap(d.points[0], d.points[1]);
  EXPECT_NE(CloudDigest(d), digest);
  // The digest of the empty cloud is SHA-256 of the canonical header alone: a fixed value.
  EXPECT_EQ(CloudDigest(PointCloud{}), CloudDigest(PointCloud{}));
}

TEST(StopCheckTest, RegistrationPreprocessingAndMatchingStopWhenAsked) {
  const PointCloud surface = testing::SampleBumpySurface(4000, -1, 1, 7);
  auto target = Target::Build(surface);
  ASSERT_TRUE(target.ok());
  RegistrationOptions options;
  options.num_samples = 2000;
  RegistrationCallbacks callbacks;
  int asked = 0;
  callbacks.should_stop = [&] { return ++asked > 3; };  // during preprocessing
  auto result = Register(**target, surface, Matrix4::Identity(), options, callbacks);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->termination, Termination::kCancelled);
  EXPECT_EQ(result->iterations, 0);
}

}  // namespace
}  // namespace mlsreg
