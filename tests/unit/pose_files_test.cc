// Pose files: rows and Stanford .conf (scanalyze's R(q)^T convention, checked against the
// bunny's ground-truth pairs), round trips and errors.
#include "mlsreg/io/pose_files.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <sstream>

#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"

namespace mlsreg {
namespace {

const std::string kBunny = std::string(MLSREG_SHARED_DATA_DIR) + "/stanford_bunny/";

TEST(PoseFilesTest, TheBunnyConfGivesTheGroundTruthOfItsPairs) {
  auto manifest = ReadManifest(kBunny + "pairs.csv");
  ASSERT_TRUE(manifest.ok()) << manifest.status();
  std::vector<std::string> scans;
  for (const ManifestProblem& p : manifest->problems) {
    scans.push_back(p.source_path);
    scans.push_back(p.target_path);
  }
  auto poses = ReadPoses(kBunny + "bun.conf", scans);
  ASSERT_TRUE(poses.ok()) << poses.status();
  for (std::size_t k = 0; k < manifest->problems.size(); ++k) {
    const ManifestProblem& p = manifest->problems[k];
    const Matrix4 relative = (*poses)[2 * k + 1].inverse() * (*poses)[2 * k];
    EXPECT_LT((relative - *p.ground_truth).cwiseAbs().maxCoeff(), 1e-6) << p.id;
  }
}

TEST(PoseFilesTest, RowsAndConfRoundTrip) {
  std::vector<Matrix4> poses;
  for (int i = 0; i < 3; ++i) {
    Matrix4 m = Matrix4::Identity();
    m.topLeftCorner<3, 3>() =
        Eigen::AngleAxisd(0.4 * i + 0.1, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    m.topRightCorner<3, 1>() = Vec3(0.1 * i, -0.2, 0.3 * i);
    poses.push_back(m);
  }
  const std::vector<std::string> scans = {"dir/a.ply", "b.ply", "/x/c.pcd"};
  auto rows = ParsePoseRows(FormatPoseRows(poses), 3);
  auto conf = ParseStanfordConf(FormatStanfordConf(poses, scans), {"c.pcd", "a.ply", "b.ply"});
  ASSERT_TRUE(rows.ok() && conf.ok());
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(((*rows)[i] - poses[i]).cwiseAbs().maxCoeff(), 1e-10);
    EXPECT_LT(((*conf)[(i + 1) % 3] - poses[i]).cwiseAbs().maxCoeff(), 1e-10);
  }
}

TEST(PoseFilesTest, BadPoseFilesNameTheLine) {
  EXPECT_EQ(ParsePoseRows("# c\n1 0 0 0 0 1 0 0 0 0 1 0 0 0 0\n", 1).status().message(),
            "poses line 2: 15 numbers, expected 16 (a row-major 4x4)");
  EXPECT_NE(
      ParsePoseRows("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n", 1).status().message().find("poses line 1"),
      std::string_view::npos);
  EXPECT_EQ(ParsePoseRows("1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n", 2).status().message(),
            "poses: 1 poses for 2 scans");
  EXPECT_EQ(ParseStanfordConf("bmesh a.ply 0 0 0 0 0 0 1\n", {"a.ply", "b.ply"}).status().message(),
            "poses: the .conf has no 'bmesh b.ply' line");
  EXPECT_EQ(
      ParseStanfordConf("camera 0 0\nbmesh a.ply 0 0 0 0 0 1\n", {"a.ply"}).status().message(),
      "conf line 2: expected 'bmesh FILE tx ty tz qi qj qk qr'");
}

}  // namespace
}  // namespace mlsreg
