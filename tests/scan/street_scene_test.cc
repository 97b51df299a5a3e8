// Procedural streets and the drive along them: seeded, valid, what each kind promises, and a
// scan of one whose points lie on the mesh within the range noise.
#include "scan/street_scene.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "gtest/gtest.h"
#include "scan/drive_path.h"
#include "scan/lidar_scanner.h"
#include "scan/ray_caster.h"

namespace mlsreg::scan {
namespace {

// The area of triangles that stand up (normal within 30 degrees of horizontal) between 0.5 m and
// 3 m above the surface at their place: what pins a sliding scan along the road.
double UprightArea(const TriangleMesh& mesh) {
  double area = 0.0;
  for (const auto& t : mesh.triangles) {
    const Vec3 &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const Vec3 n = (b - a).cross(c - a);
    if (n.norm() == 0.0 || std::abs(n.normalized().z()) > 0.5) continue;
    area += 0.5 * n.norm();
  }
  return area;
}

TEST(StreetSceneTest, TheSameSeedGivesTheSameMeshAndAnotherSeedAnother) {
  for (StreetKind kind : {StreetKind::kStreet, StreetKind::kCorridor, StreetKind::kOpenRoad}) {
    SCOPED_TRACE(StreetKindName(kind));
    const TriangleMesh a = BuildStreetScene({kind, 7});
    const TriangleMesh b = BuildStreetScene({kind, 7});
    const TriangleMesh c = BuildStreetScene({kind, 8});
    EXPECT_TRUE(ValidateTriangleMesh(a).ok());
    EXPECT_EQ(a.vertices, b.vertices);
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_NE(a.vertices, c.vertices);
  }
}

TEST(StreetSceneTest, KindsHaveTheirCharacter) {
  for (std::uint64_t seed : {1, 2, 3}) {
    const StreetLayout street = MakeStreetLayout({StreetKind::kStreet, seed});
    EXPECT_GE(street.length_m, 200.0);
    EXPECT_LE(street.length_m, 300.0);
    EXPECT_NEAR(street.curb_height_m, 0.15, 1e-12);
    // A bend, when there is one, is gentle: a radius of at least 130 m.
    if (street.bend_angle_rad != 0.0) {
      EXPECT_GE(street.bend_length_m / std::abs(street.bend_angle_rad), 130.0 - 1e-9);
    }
    EXPECT_EQ(MakeStreetLayout({StreetKind::kCorridor, seed}).bend_angle_rad, 0.0);
    EXPECT_EQ(MakeStreetLayout({StreetKind::kOpenRoad, seed}).curb_height_m, 0.0);
    // The open road has far less standing structure than a street or a corridor.
    const double street_upright = UprightArea(BuildStreetScene({StreetKind::kStreet, seed}));
    const double open_upright = UprightArea(BuildStreetScene({StreetKind::kOpenRoad, seed}));
    const double corridor_upright = UprightArea(BuildStreetScene({StreetKind::kCorridor, seed}));
    EXPECT_LT(open_upright * 10.0, street_upright);
    EXPECT_LT(open_upright * 10.0, corridor_upright);
  }
  EXPECT_EQ(*ParseStreetKind("open_road"), StreetKind::kOpenRoad);
  const auto bad = ParseStreetKind("highway");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("--scene"), std::string::npos);
}

TEST(StreetSceneTest, TheCurbIsAStepOfFifteenCentimetres) {
  const StreetLayout layout = MakeStreetLayout({StreetKind::kStreet, 4});
  const double w = layout.road_half_width_m;
  for (double s : {0.0, 50.0, 120.0}) {
    for (double side : {1.0, -1.0}) {
      const double road = layout.SurfaceHeight(s, side * (w - 1e-6));
      const double walk = layout.SurfaceHeight(s, side * (w + 1e-6));
      EXPECT_NEAR(walk - road, 0.15, 1e-4);
    }
  }
  // Across a side street the curb is gone.
  int side_streets = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const StreetLayout other = MakeStreetLayout({StreetKind::kStreet, seed});
    for (const auto& [start, end] : other.cross_streets) {
      ++side_streets;
      EXPECT_GE(end - start, 10.0);
      const double mid = 0.5 * (start + end), edge = other.road_half_width_m;
      EXPECT_NEAR(other.SurfaceHeight(mid, edge + 1e-6), other.SurfaceHeight(mid, edge - 1e-6),
                  1e-4);
    }
  }
  EXPECT_GT(side_streets, 0);
  // World(s, u) is u metres to the left of the centreline, whatever the bend.
  for (double s : {10.0, 100.0, 200.0}) {
    const Vec3 center = layout.World(s, 0.0, 0.0), left = layout.World(s, 3.0, 0.0);
    const Vec3 ahead = layout.World(s + 0.01, 0.0, 0.0) - center;
    EXPECT_NEAR((left - center).norm(), 3.0, 1e-9);
    EXPECT_NEAR(ahead.normalized().cross(left - center).z(), 3.0, 1e-6);
  }
}

TEST(DrivePathTest, TheDriveKeepsItsLaneAtCitySpeedsWithSlightYaw) {
  const StreetLayout layout = MakeStreetLayout({StreetKind::kStreet, 2});
  const Drive drive = DriveAlongStreet(layout, DriveOptions{});
  ASSERT_GT(drive.base_to_world.size(), 100u);
  const std::vector<double> travelled = TravelledDistances(drive);
  EXPECT_GT(travelled.back(), layout.length_m - 40.0);
  for (std::size_t k = 0; k < drive.base_to_world.size(); ++k) {
    const Matrix4& pose = drive.base_to_world[k];
    ASSERT_TRUE(CheckRigid(pose, "pose").ok());
    // Upright within the road's slope and camber.
    EXPECT_GT(pose(2, 2), std::cos(4.0 * std::numbers::pi / 180.0));
    if (k == 0) continue;
    const double step = travelled[k] - travelled[k - 1];
    EXPECT_GE(step, 0.7 - 1e-3);
    EXPECT_LE(step, 1.5 + 0.05);
    const Eigen::Matrix3d turn =
        drive.base_to_world[k - 1].topLeftCorner<3, 3>().transpose() * pose.topLeftCorner<3, 3>();
    EXPECT_LT(Eigen::AngleAxisd(turn).angle() * 180.0 / std::numbers::pi, 1.0) << "frame " << k;
  }
  EXPECT_EQ(DriveAlongStreet(layout, {.frames = 25}).base_to_world.size(), 25u);
}

TEST(DrivePathTest, PairsAreTheFramesNearestTheGapsSourceLater) {
  std::vector<double> travelled;
  for (int k = 0; k < 200; ++k) travelled.push_back(1.1 * k);
  const auto pairs = SelectFramePairs(travelled, {4.0, 8.0, 12.0}, 16);
  ASSERT_TRUE(pairs.ok());
  ASSERT_EQ(pairs->size(), 16u);
  for (std::size_t i = 0; i < pairs->size(); ++i) {
    const FramePair& p = (*pairs)[i];
    EXPECT_GT(p.source, p.target);
    EXPECT_EQ(p.gap_m, (std::vector<double>{4.0, 8.0, 12.0})[i % 3]);
    EXPECT_LE(std::abs(travelled[p.source] - travelled[p.target] - p.gap_m), 0.55 + 1e-9);
  }
  EXPECT_EQ(pairs->front().target, 0);
  EXPECT_GT(pairs->back().target, 150);  // spread over the drive
  EXPECT_FALSE(SelectFramePairs(travelled, {-1.0}, 4).ok());
  EXPECT_FALSE(SelectFramePairs(travelled, {500.0}, 4).ok());
  EXPECT_FALSE(SelectFramePairs(travelled, {4.0}, 0).ok());
  // A short drive gives fewer, distinct pairs.
  const auto few = SelectFramePairs({0.0, 1.0, 2.0, 3.0, 4.0, 5.0}, {4.0}, 16);
  ASSERT_TRUE(few.ok());
  EXPECT_EQ(few->size(), 2u);
}

TEST(StreetSceneTest, AStreetScanLiesOnTheSceneWithinTheRangeNoise) {
  const StreetSceneOptions options{StreetKind::kStreet, 3};
  const TriangleMesh mesh = BuildStreetScene(options);
  auto caster = RayCaster::Build(mesh);
  ASSERT_TRUE(caster.ok());
  const Drive drive = DriveAlongStreet(MakeStreetLayout(options), {.frames = 60});
  LidarOptions lidar;
  lidar.range_noise_sigma_m = 0.02;
  const Matrix4 pose = SensorPose(drive.base_to_world[50], lidar.sensor_height_m);
  const PointCloud cloud = RenderLidarScan(**caster, pose, lidar, 3, 2);
  // KITTI-like: about 100k points, dense rings near the car, sparse far away.
  EXPECT_GT(cloud.size(), 80000u);
  EXPECT_LT(cloud.size(), 64u * 1800u);
  std::vector<double> ranges;
  for (const Vec3& p : cloud.points) ranges.push_back(p.norm());
  std::sort(ranges.begin(), ranges.end());
  EXPECT_GT(ranges[ranges.size() / 2], 5.0);
  EXPECT_LT(ranges[ranges.size() / 2], 20.0);
  EXPECT_GT(ranges[ranges.size() * 99 / 100], 30.0);
  EXPECT_LE(ranges.back(), 80.0 + 0.2);
  // Each point is on its ray's first hit of the scene, within 4 sigma.
  const Eigen::Matrix3d rotation = pose.topLeftCorner<3, 3>();
  const Vec3 origin = pose.topRightCorner<3, 1>();
  // (The noise is Gaussian: of some 6800 points, about 0.4 are expected beyond 4 sigma.)
  int checked = 0, beyond_4_sigma = 0;
  for (std::size_t i = 0; i < cloud.size(); i += 17) {
    const Vec3& p = cloud.points[i];
    const auto hit = (*caster)->Cast(origin, rotation * p.normalized());
    ASSERT_TRUE(hit.has_value()) << "point " << i;
    const double off = std::abs(hit->distance - p.norm());
    ASSERT_LT(off, 6.0 * lidar.range_noise_sigma_m) << "point " << i;
    if (off > 4.0 * lidar.range_noise_sigma_m) ++beyond_4_sigma;
    ++checked;
  }
  EXPECT_GT(checked, 4000);
  EXPECT_LE(beyond_4_sigma, 3);
}

}  // namespace
}  // namespace mlsreg::scan
