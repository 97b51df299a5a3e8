// The evaluation's start-pose protocol is one function: `register --perturb-*` and `eval` share it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>

#include "absl/strings/str_cat.h"
#include "mlsreg/evaluation/evaluation.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/evaluation/shard.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

TEST(PerturbedStartTest, RotatesAboutThePlacedCentroidByTheAngleAndMovesByTheDistance) {
  const PointCloud source = testing::SampleBumpySurface(500, -1, 1, 9);
  Matrix4 initial = Matrix4::Identity();
  initial.topRightCorner<3, 1>() = Vec3(5, -2, 1);
  const double d = 0.01;
  const PerturbationProtocol protocol{10.0, 10.0, 7};
  const Matrix4 start = PerturbedStart(source, initial, d, protocol);
  const PoseError error = EvaluatePose(source.points, start, initial, d);
  EXPECT_NEAR(error.rotation_deg, 10.0, 1e-9);
  // The rotation is about the centroid as `initial` places it: the centroid moves by the
  // translation alone.
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : source.points) centroid += p;
  centroid /= static_cast<double>(source.size());
  const Vec3 placed = initial.topLeftCorner<3, 3>() * centroid + initial.topRightCorner<3, 1>();
  const Vec3 moved = start.topLeftCorner<3, 3>() * centroid + start.topRightCorner<3, 1>();
  EXPECT_NEAR((moved - placed).norm(), 10.0 * d, 1e-12);
  // Deterministic per (seed, index); problem 0 is what `register` uses.
  EXPECT_EQ(PerturbedStart(source, initial, d, protocol, 0), start);
  EXPECT_NE(PerturbedStart(source, initial, d, protocol, 1), start);
  EXPECT_EQ(PerturbedStart(source, initial, d, {0.0, 0.0, 7}), initial);
}

// ---- shards (evaluation/shard.h)

Manifest ManifestOfTargets(const std::vector<std::string>& targets) {
  Manifest manifest;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    ManifestProblem p;
    p.id = absl::StrCat("p", i);
    p.source_path = absl::StrCat("s", i, ".ply");
    p.target_path = targets[i];
    manifest.problems.push_back(p);
  }
  return manifest;
}

TEST(ShardTest, ShardsPartitionTheProblemsKeepTargetsWholeAndBalance) {
  // Targets with 5, 3, 3, 2, 1 and 1 problems, interleaved.
  const Manifest manifest =
      ManifestOfTargets({"a", "b", "a", "c", "a", "b", "d", "a", "c", "b", "e", "a", "f", "d"});
  for (int count : {1, 2, 3, 4, 20}) {
    std::vector<int> shard_of(manifest.problems.size(), -1);
    std::vector<std::size_t> sizes;
    for (int i = 0; i < count; ++i) {
      const std::vector<std::size_t> mine = ShardProblems(manifest, {i, count});
      EXPECT_TRUE(std::is_sorted(mine.begin(), mine.end()));
      EXPECT_EQ(mine, ShardProblems(manifest, {i, count}));  // deterministic
      for (std::size_t p : mine) {
        EXPECT_EQ(shard_of[p], -1) << "problem " << p << " in two shards";
        shard_of[p] = i;
      }
      sizes.push_back(mine.size());
    }
    for (std::size_t p = 0; p < manifest.problems.size(); ++p) {
      ASSERT_NE(shard_of[p], -1) << "problem " << p << " in no shard of " << count;
      for (std::size_t q = 0; q < p; ++q) {
        if (manifest.problems[p].target_path == manifest.problems[q].target_path) {
          EXPECT_EQ(shard_of[p], shard_of[q]) << "a target split over shards";
        }
      }
    }
    if (count == 3) {  // a to shard 0, b 1, c 2, d 2, e 1, f 1: 5, 5 and 4 problems
      EXPECT_EQ(*std::max_element(sizes.begin(), sizes.end()), 5u);
      EXPECT_EQ(*std::min_element(sizes.begin(), sizes.end()), 4u);
    }
  }
}

TEST(ShardTest, ParsesIOverNAndNamesTheFlagWhenItCannot) {
  const absl::StatusOr<ShardSpec> ok = ParseShard("2/8");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok->index, 2);
  EXPECT_EQ(ok->count, 8);
  for (const char* bad : {"8/8", "-1/8", "1", "a/b", "1/0", "1/2/3", ""}) {
    const absl::StatusOr<ShardSpec> parsed = ParseShard(bad);
    EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_THAT(std::string(parsed.status().message()), ::testing::HasSubstr("--shard")) << bad;
  }
}

TEST(ShardTest, ShardFromTheEnvironmentReadsTheJobCompletionIndex) {
  ::setenv("MLSREG_TEST_SHARD_INDEX", "3", 1);
  const absl::StatusOr<ShardSpec> shard = ShardFromEnvironment(4, "MLSREG_TEST_SHARD_INDEX");
  ASSERT_TRUE(shard.ok()) << shard.status();
  EXPECT_EQ(shard->index, 3);
  EXPECT_EQ(ShardFromEnvironment(3, "MLSREG_TEST_SHARD_INDEX").status().code(),
            absl::StatusCode::kInvalidArgument);
  ::unsetenv("MLSREG_TEST_SHARD_INDEX");
  const absl::StatusOr<ShardSpec> unset = ShardFromEnvironment(4, "MLSREG_TEST_SHARD_INDEX");
  EXPECT_THAT(std::string(unset.status().message()),
              ::testing::HasSubstr("MLSREG_TEST_SHARD_INDEX is not set"));
}

}  // namespace
}  // namespace mlsreg
