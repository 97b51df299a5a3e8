// Target::WithMovedPoints, the smoothed target of ST-SICP.
#include "mlsreg/geometry/target.h"

#include "gtest/gtest.h"
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

}  // namespace
}  // namespace mlsreg
