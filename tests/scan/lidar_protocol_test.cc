// The LiDAR protocol's files: the manifest's gt brings a source scan onto its target's surfaces,
// pairs_identity.csv starts from the identity, the same seed writes the same bytes, movers break
// the static world but not the gt, a user's mesh can be driven through, bad options are refused.
#include "scan/lidar_protocol.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <filesystem>

#include "gtest/gtest.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "scan/test_meshes.h"

namespace mlsreg::scan {
namespace {

std::string Slurp(const std::string& path) {
  auto bytes = ReadFileBytes(path);
  return bytes.ok() ? *bytes : std::string();
}

// Distances of `points` (mapped by `m`) to the plane fitted through their 8 nearest target points,
// for those within `range` of the target sensor; sorted.
std::vector<double> PointToPlaneDistances(const std::vector<Vec3>& points, const Matrix4& m,
                                          const PointCloud& target, const KdTree& tree,
                                          double range) {
  std::vector<double> distances;
  std::uint32_t indices[8];
  double squared[8];
  for (std::size_t i = 0; i < points.size(); i += 7) {
    const Vec3 p = m.topLeftCorner<3, 3>() * points[i] + m.topRightCorner<3, 1>();
    if (p.norm() > range) continue;
    if (tree.Knn(p, 8, indices, squared) < 8) continue;
    Vec3 mean = Vec3::Zero();
    for (std::uint32_t k : indices) mean += target.points[k];
    mean /= 8.0;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (std::uint32_t k : indices) {
      covariance += (target.points[k] - mean) * (target.points[k] - mean).transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
    distances.push_back(std::abs(solver.eigenvectors().col(0).dot(p - mean)));
  }
  std::sort(distances.begin(), distances.end());
  return distances;
}

class LidarProtocolTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // One folder per test: ctest runs the tests of this suite in parallel processes.
    out_ = ::testing::TempDir() + "/lidar_protocol_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::remove_all(out_);
  }
  void TearDown() override { std::filesystem::remove_all(out_); }
  std::string out_;
};

TEST_F(LidarProtocolTest, GroundTruthBringsEachSourceScanOntoItsTargetsSurfaces) {
  const LidarScene scene = MakeStreetLidarScene({StreetKind::kStreet, 5}, {.frames = 40});
  LidarProtocolOptions options;
  options.noise_sigmas_m = {0.0, 0.02};
  options.pair_gaps_m = {4.0, 8.0};
  options.pairs = 3;
  options.threads = 2;
  const auto summary = WriteLidarProtocol(scene, "street_s5", out_, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->pairs, 3);
  EXPECT_EQ(summary->frames, 40);
  EXPECT_GT(summary->min_points, 80000u);
  ASSERT_EQ(summary->manifests.size(), 2u);
  EXPECT_EQ(summary->manifests[1], out_ + "/street_s5/noise0.02/pairs.csv");
  EXPECT_TRUE(std::filesystem::exists(out_ + "/street_s5/poses.csv"));

  const auto manifest = ReadManifest(summary->manifests[0]);
  ASSERT_TRUE(manifest.ok()) << manifest.status();
  ASSERT_EQ(manifest->problems.size(), 3u);
  EXPECT_EQ(manifest->extra_columns,
            (std::vector<std::string>{"distance_m", "rotation_deg", "scene", "noise_sigma_m",
                                      "source_frame", "target_frame"}));
  for (const ManifestProblem& problem : manifest->problems) {
    SCOPED_TRACE(problem.id);
    ASSERT_TRUE(problem.ground_truth.has_value());
    EXPECT_FALSE(problem.initial.has_value());
    EXPECT_GT(std::stoi(problem.extra[4].second), std::stoi(problem.extra[5].second));
    const Matrix4& gt = *problem.ground_truth;
    const double distance = gt.topRightCorner<3, 1>().norm();
    EXPECT_NEAR(distance, std::stod(problem.extra[0].second), 1e-5);
    // The later frame is ahead: in the target's frame the source sensor sits forward.
    EXPECT_GT(gt(0, 3), 3.0);
    const auto source = ReadPointCloud(problem.source_path);
    const auto target = ReadPointCloud(problem.target_path);
    ASSERT_TRUE(source.ok() && target.ok());
    const KdTree tree(target->points);
    const std::vector<double> right =
        PointToPlaneDistances(source->points, gt, *target, tree, 20.0);
    ASSERT_GT(right.size(), 5000u);
    EXPECT_LT(right[right.size() / 2], 0.01);
    EXPECT_LT(right[right.size() * 3 / 4], 0.03);
    // A pose 20 cm off (sideways and up) does not fit.
    Matrix4 wrong = gt;
    wrong(1, 3) += 0.2;
    wrong(2, 3) += 0.2;
    const std::vector<double> off =
        PointToPlaneDistances(source->points, wrong, *target, tree, 20.0);
    EXPECT_GT(off[off.size() / 2], 0.1);
  }

  // pairs_identity.csv: the same rows, starting from the identity.
  const auto identity = ReadManifest(out_ + "/street_s5/noise0.02/pairs_identity.csv");
  const auto noisy = ReadManifest(summary->manifests[1]);
  ASSERT_TRUE(identity.ok() && noisy.ok());
  ASSERT_EQ(identity->problems.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(identity->problems[i].initial.has_value());
    EXPECT_TRUE(identity->problems[i].initial->isIdentity());
    EXPECT_EQ(identity->problems[i].id, noisy->problems[i].id);
    EXPECT_EQ(*identity->problems[i].ground_truth, *manifest->problems[i].ground_truth);
    EXPECT_EQ(identity->problems[i].source_path, noisy->problems[i].source_path);
  }
  EXPECT_NE(Slurp(manifest->problems[0].source_path), Slurp(noisy->problems[0].source_path));
}

TEST_F(LidarProtocolTest, TheSameSeedWritesTheSameBytesWhateverTheThreads) {
  const LidarScene scene = MakeStreetLidarScene({StreetKind::kOpenRoad, 2}, {.frames = 30});
  LidarProtocolOptions options;
  options.noise_sigmas_m = {0.03};
  options.pair_gaps_m = {6.0};
  options.pairs = 2;
  options.movers = 12;
  options.threads = 1;
  ASSERT_TRUE(WriteLidarProtocol(scene, "same", out_ + "/one", options).ok());
  options.threads = 2;
  ASSERT_TRUE(WriteLidarProtocol(scene, "same", out_ + "/two", options).ok());
  for (const std::string file :
       {"noise0.03/pairs.csv", "noise0.03/pairs_identity.csv", "poses.csv"}) {
    EXPECT_EQ(Slurp(out_ + "/one/same/" + file), Slurp(out_ + "/two/same/" + file)) << file;
  }
  int scans = 0;
  for (const auto& entry : std::filesystem::directory_iterator(out_ + "/one/same/noise0.03")) {
    if (entry.path().extension() != ".ply") continue;
    const std::string name = entry.path().filename().string();
    const std::string bytes = Slurp(entry.path().string());
    EXPECT_GT(bytes.size(), 1000000u);
    EXPECT_EQ(bytes, Slurp(out_ + "/two/same/noise0.03/" + name)) << name;
    ++scans;
  }
  EXPECT_EQ(scans, 4);
  // And a scene rebuilt from its seed is the same scene.
  const LidarScene again = MakeStreetLidarScene({StreetKind::kOpenRoad, 2}, {.frames = 30});
  EXPECT_EQ(again.mesh.vertices, scene.mesh.vertices);
  EXPECT_EQ(again.drive.base_to_world, scene.drive.base_to_world);
}

TEST_F(LidarProtocolTest, MoversChangeTheScansButNotTheGroundTruth) {
  const LidarScene scene = MakeStreetLidarScene({StreetKind::kStreet, 6}, {.frames = 60});
  LidarProtocolOptions options;
  options.noise_sigmas_m = {0.0};
  options.pair_gaps_m = {8.0};
  options.pairs = 3;
  options.threads = 2;
  ASSERT_TRUE(WriteLidarProtocol(scene, "still", out_, options).ok());
  options.movers = 40;
  ASSERT_TRUE(WriteLidarProtocol(scene, "busy", out_, options).ok());
  const auto still = ReadManifest(out_ + "/still/noise0/pairs.csv");
  const auto busy = ReadManifest(out_ + "/busy/noise0/pairs.csv");
  ASSERT_TRUE(still.ok() && busy.ok());
  ASSERT_EQ(still->problems.size(), busy->problems.size());
  int changed = 0;
  for (std::size_t i = 0; i < still->problems.size(); ++i) {
    EXPECT_EQ(*still->problems[i].ground_truth, *busy->problems[i].ground_truth);
    const auto a = ReadPointCloud(still->problems[i].source_path);
    const auto b = ReadPointCloud(busy->problems[i].source_path);
    ASSERT_TRUE(a.ok() && b.ok());
    if (a->points != b->points) ++changed;
  }
  EXPECT_GT(changed, 0);
}

TEST_F(LidarProtocolTest, DrivesStraightThroughAUsersMesh) {
  // A 60 m x 20 m floor at z = 3 with a wall along either side.
  TriangleMesh mesh;
  mesh.vertices = {Vec3(0, -10, 3), Vec3(60, -10, 3), Vec3(60, 10, 3),  Vec3(0, 10, 3),
                   Vec3(0, -8, 0),  Vec3(60, -8, 0),  Vec3(60, -8, 10), Vec3(0, -8, 10),
                   Vec3(0, 8, 0),   Vec3(60, 8, 0),   Vec3(60, 8, 10),  Vec3(0, 8, 10)};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {8, 9, 10}, {8, 10, 11}};
  auto scene = MakeMeshLidarScene(mesh, {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_GT(scene->drive.base_to_world.size(), 30u);
  for (const Matrix4& base : scene->drive.base_to_world) {
    EXPECT_NEAR(base(2, 3), 3.0, 1e-6);  // on the floor
    EXPECT_NEAR(base(1, 3), 0.0, 1e-9);  // along the middle
    EXPECT_GE(base(0, 3), 3.0 - 1e-9);
    EXPECT_LE(base(0, 3), 57.0 + 1e-9);
  }
  LidarProtocolOptions options;
  options.noise_sigmas_m = {0.01};
  options.pairs = 4;
  const auto summary = WriteLidarProtocol(*scene, "hall", out_, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  EXPECT_EQ(summary->pairs, 4);

  const auto tiny = MakeMeshLidarScene(UvSphere(Vec3::Zero(), 1.0, 10, 20), {});
  EXPECT_EQ(tiny.status().code(), absl::StatusCode::kFailedPrecondition);
}

TEST_F(LidarProtocolTest, RefusesBadOptionsNamingTheFlag) {
  const LidarScene scene = MakeStreetLidarScene({StreetKind::kCorridor, 1}, {.frames = 20});
  // The message of the error for the default options changed by `change`.
  auto message_of = [&](auto change) {
    LidarProtocolOptions o;
    change(o);
    const auto result = WriteLidarProtocol(scene, "x", out_, o);
    EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(result.status().message());
  };
  using O = LidarProtocolOptions;
  EXPECT_NE(message_of([](O& o) {
              o.noise_sigmas_m = {0.01, -0.02};
            }).find("--noise-m"),
            std::string::npos);
  EXPECT_NE(message_of([](O& o) { o.pair_gaps_m = {0.0}; }).find("--pair-gaps"), std::string::npos);
  // Longer than the 20-frame drive.
  EXPECT_NE(message_of([](O& o) {
              o.pair_gaps_m = {4.0, 100.0};
            }).find("--pair-gaps"),
            std::string::npos);
  EXPECT_NE(message_of([](O& o) { o.movers = -1; }).find("--movers"), std::string::npos);
  EXPECT_NE(message_of([](O& o) { o.lidar.azimuth_step_deg = 1.0; }).find("--azimuth-step"),
            std::string::npos);
  EXPECT_NE(message_of([](O& o) { o.pairs = 0; }).find("--pairs"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(out_ + "/x"));
  EXPECT_EQ(ValidateDriveOptions({.frames = 1}).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ValidateDriveOptions({.min_step_m = 2.0, .max_step_m = 1.0}).code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlsreg::scan
