// Target::WithMovedPoints, the smoothed target of ST-SICP; the memory a cached target holds, as
// docs/operations.md plans capacity with it.
#include "mlsreg/geometry/target.h"

#include <cmath>
#include <regex>
#include <string>

#include "gtest/gtest.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

TEST(TargetTest, WithMovedPointsRebuildsGeometryButKeepsSurfaceVariation) {
  // A noisy plane: real surface variation. Flattening it (z = 0) would give ~0 everywhere.
  const PointCloud noisy = testing::SamplePlaneGrid(0.5, 0.02, 0.005, 3, /*noise=*/0.01);
  auto target = Target::Build(noisy);
  ASSERT_TRUE(target.ok()) << target.status();
  std::vector<Vec3> flat = (*target)->points();
  for (Vec3& p : flat) p.z() = 0.0;
  auto moved = (*target)->WithMovedPoints(flat);
  ASSERT_TRUE(moved.ok()) << moved.status();
  EXPECT_EQ((*moved)->points(), flat);
  EXPECT_EQ((*moved)->surface().curvature, (*target)->surface().curvature);
  for (std::size_t i = 0; i < flat.size(); i += 37) {
    EXPECT_NEAR(std::abs((*moved)->surface().normals[i].z()), 1.0, 1e-9);  // rebuilt: flat
  }
  auto rebuilt = Target::Build(PointCloud{flat});
  ASSERT_TRUE(rebuilt.ok());
  EXPECT_LT((*rebuilt)->surface().curvature[flat.size() / 2],
            0.1 * (*target)->surface().curvature[flat.size() / 2]);
  EXPECT_EQ((*target)->WithMovedPoints({Vec3::Zero()}).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// A target that makes its parts on first use registers exactly as one that made them all at
// build, with every method that uses them (MLS patches, surface, features), and holds less
// until they are asked for.
TEST(TargetTest, PartsMadeOnFirstUseGiveTheSameRegistrations) {
  auto target_cloud = ReadPointCloud(MLSREG_SOURCE_DIR "/data/bunny/bun045.ply");
  auto source = ReadPointCloud(MLSREG_SOURCE_DIR "/data/bunny/bun000.ply");
  ASSERT_TRUE(target_cloud.ok() && source.ok());
  auto eager = Target::Build(*target_cloud, TargetOptions::AllWithTarget());
  auto lazy = Target::Build(*target_cloud);
  ASSERT_TRUE(eager.ok() && lazy.ok());
  EXPECT_LT((*lazy)->MemoryBytes(), (*eager)->MemoryBytes());
  EXPECT_EQ((*lazy)->mls_patches()->fitted(), 0u);
  for (Method method : {Method::kAuto, Method::kMlsSicp, Method::kCpSicp, Method::kGicp}) {
    RegistrationOptions options;
    options.method = method;
    options.num_samples = 500;
    auto a = Register(**eager, *source, Matrix4::Identity(), options);
    auto b = Register(**lazy, *source, Matrix4::Identity(), options);
    ASSERT_TRUE(a.ok() && b.ok()) << MethodName(method);
    EXPECT_EQ(a->transform, b->transform) << MethodName(method);
    EXPECT_EQ(a->iterations, b->iterations) << MethodName(method);
  }
  EXPECT_GT((*lazy)->mls_patches()->fitted(), 0u);
  EXPECT_LT((*lazy)->mls_patches()->fitted(), (*lazy)->mls_patches()->size());
}

// docs/operations.md sizes the cache with the bytes per point a cached target holds. This is
// the measurement: the bundled 40k-point bun045 scan built with the options a server caches
// targets with (kd-tree, normals, curvature, MLS patch storage, FPFH features). The line and every
// use of the number in its formulas must state it (to the byte per point).
TEST(TargetTest, DocsStateTheBytesPerPointOfACachedTarget) {
  auto cloud = ReadPointCloud(MLSREG_SOURCE_DIR "/data/bunny/bun045.ply");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  const std::size_t points = cloud->size();
  auto target = Target::Build(*std::move(cloud), TargetOptions::ForServing());
  ASSERT_TRUE(target.ok()) << target.status();
  const double per_point = static_cast<double>((*target)->MemoryBytes()) / points;
  auto docs = ReadFileBytes(MLSREG_SOURCE_DIR "/docs/operations.md");
  ASSERT_TRUE(docs.ok()) << docs.status();
  std::smatch stated;
  ASSERT_TRUE(std::regex_search(*docs, stated,
                                std::regex(R"(Memory per cached target: (\d+) bytes per point)")));
  const int documented = std::stoi(stated[1]);
  EXPECT_LE(std::abs(documented - per_point), 1.0)
      << "docs/operations.md says " << documented << " bytes per point; a cached " << points
      << "-point target holds " << per_point << ": update its capacity planning";
  const std::string text = *docs;
  const std::regex formula(R"((\d+) B \* P)");
  for (std::sregex_iterator it(text.begin(), text.end(), formula), end; it != end; ++it) {
    EXPECT_EQ(std::stoi((*it)[1]), documented) << "a formula uses " << (*it)[0];
  }
}

}  // namespace
}  // namespace mlsreg
