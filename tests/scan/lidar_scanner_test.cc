// The spinning LiDAR: rings over a ground plane at their analytic ranges in the sensor frame, the
// range noise it was asked for, ring-by-ring order, the carrying car's shadow, determinism, and
// the options it refuses.
#include "scan/lidar_scanner.h"

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <numbers>

#include "gtest/gtest.h"
#include "scan/ray_caster.h"

namespace mlsreg::scan {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// A flat square of half-size `half` at z = 0, split into a fan of triangles.
TriangleMesh GroundPlane(double half) {
  TriangleMesh mesh;
  mesh.vertices = {Vec3(-half, -half, 0), Vec3(half, -half, 0), Vec3(half, half, 0),
                   Vec3(-half, half, 0)};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

Matrix4 SensorAt(const Vec3& position, double yaw_deg) {
  Matrix4 pose = Matrix4::Identity();
  pose.topLeftCorner<3, 3>() = Eigen::AngleAxisd(yaw_deg * kDeg, Vec3::UnitZ()).toRotationMatrix();
  pose.topRightCorner<3, 1>() = position;
  return pose;
}

// The ring of a point: the beam whose elevation is nearest the point's (noise along the ray keeps
// the direction).
int RingOf(const Vec3& p, const std::vector<double>& elevations) {
  const double e = std::asin(p.z() / p.norm()) / kDeg;
  int best = 0;
  for (int k = 1; k < static_cast<int>(elevations.size()); ++k) {
    if (std::abs(elevations[k] - e) < std::abs(elevations[best] - e)) best = k;
  }
  return best;
}

TEST(LidarScannerTest, RingsOverAGroundPlaneLieAtTheAnalyticRangeWithTheRequestedNoise) {
  const TriangleMesh plane = GroundPlane(2000.0);
  auto caster = RayCaster::Build(plane);
  ASSERT_TRUE(caster.ok());
  LidarOptions options;
  options.ego_body = false;
  options.max_range_m = 80.0;
  options.range_noise_sigma_m = 0.02;
  const double h = 1.73;
  // Anywhere, facing anywhere: the cloud is in the sensor's frame.
  const PointCloud cloud =
      RenderLidarScan(**caster, SensorAt(Vec3(120.0, -35.0, h), 37.0), options, 5, 2);
  ASSERT_TRUE(cloud.viewpoint.has_value());
  EXPECT_EQ(*cloud.viewpoint, Vec3::Zero());
  const std::vector<double> elevations = BeamElevationsDeg(options);
  ASSERT_EQ(elevations.size(), 64u);
  EXPECT_DOUBLE_EQ(elevations.front(), 2.0);
  EXPECT_DOUBLE_EQ(elevations.back(), -24.8);

  std::map<int, int> per_ring;
  double sum = 0.0, sum_squared = 0.0;
  int previous_ring = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3& p = cloud.points[i];
    const int ring = RingOf(p, elevations);
    ASSERT_GE(ring, previous_ring) << "point " << i << ": not ring by ring";
    previous_ring = ring;
    ++per_ring[ring];
    // The ground is at z = -h in the sensor frame: range h / sin(-elevation), horizontal
    // distance h / tan(-elevation).
    const double expected = h / std::sin(-elevations[ring] * kDeg);
    const double error = p.norm() - expected;
    ASSERT_LT(std::abs(error), 5.0 * options.range_noise_sigma_m) << "point " << i;
    sum += error;
    sum_squared += error * error;
  }
  // Every beam that meets the ground within 80 m gives a full ring, the others nothing.
  const int steps = AzimuthSteps(options);
  EXPECT_EQ(steps, 1800);
  for (int ring = 0; ring < 64; ++ring) {
    const double e = elevations[ring] * kDeg;
    const bool reaches = e < 0.0 && h / std::sin(-e) <= options.max_range_m;
    EXPECT_EQ(per_ring[ring], reaches ? steps : 0) << "ring " << ring << " at " << elevations[ring];
  }
  const double n = static_cast<double>(cloud.size());
  const double mean = sum / n, sigma = std::sqrt(sum_squared / n - mean * mean);
  EXPECT_NEAR(sigma, options.range_noise_sigma_m, 0.1 * options.range_noise_sigma_m);
  EXPECT_NEAR(mean, 0.0, 0.05 * options.range_noise_sigma_m);
}

TEST(LidarScannerTest, TheCarriersRoofShadowsTheLowestBeamsBehindAndAhead) {
  const TriangleMesh plane = GroundPlane(500.0);
  auto caster = RayCaster::Build(plane);
  ASSERT_TRUE(caster.ok());
  LidarOptions options;
  const PointCloud cloud = RenderLidarScan(**caster, SensorAt(Vec3(0, 0, 1.73), 0.0), options, 1);
  const std::vector<double> elevations = BeamElevationsDeg(options);
  struct Sectors {
    int behind = 0, ahead = 0, beside = 0;
  };
  auto lowest_ring = [&](const PointCloud& c) {
    Sectors s;
    for (const Vec3& p : c.points) {
      if (RingOf(p, elevations) != 63) continue;
      const double azimuth = std::atan2(p.y(), p.x()) / kDeg;
      if (std::abs(azimuth) > 170.0) ++s.behind;
      if (std::abs(azimuth) < 10.0) ++s.ahead;
      if (std::abs(std::abs(azimuth) - 90.0) < 10.0) ++s.beside;
    }
    return s;
  };
  const Sectors shadowed = lowest_ring(cloud);
  options.ego_body = false;
  const PointCloud bare = RenderLidarScan(**caster, SensorAt(Vec3(0, 0, 1.73), 0.0), options, 1);
  const Sectors whole = lowest_ring(bare);
  EXPECT_GT(whole.behind, 90);
  EXPECT_EQ(shadowed.behind, 0);
  EXPECT_EQ(shadowed.ahead, 0);
  EXPECT_EQ(shadowed.beside, whole.beside);  // the roof is narrower than it is long
  EXPECT_LT(cloud.size(), bare.size());
  EXPECT_GT(cloud.size(), bare.size() * 9 / 10);
}

TEST(LidarScannerTest, TheNearestOfSeveralCastersWinsAndMinRangeDropsTheCar) {
  const TriangleMesh plane = GroundPlane(500.0);
  TriangleMesh wall;  // a wall 10 m ahead, 40 m wide
  wall.vertices = {Vec3(10, -20, -5), Vec3(10, 20, -5), Vec3(10, 20, 20), Vec3(10, -20, 20)};
  wall.triangles = {{0, 1, 2}, {0, 2, 3}};
  TriangleMesh box;  // a wall 2 m ahead: inside the minimum range
  box.vertices = {Vec3(2, -0.5, -5), Vec3(2, 0.5, -5), Vec3(2, 0.5, 5), Vec3(2, -0.5, 5)};
  box.triangles = {{0, 1, 2}, {0, 2, 3}};
  auto ground = RayCaster::Build(plane);
  auto front = RayCaster::Build(wall);
  auto near = RayCaster::Build(box);
  ASSERT_TRUE(ground.ok() && front.ok() && near.ok());
  LidarOptions options;
  options.ego_body = false;
  const RayCaster* world[] = {ground->get(), front->get(), near->get()};
  const PointCloud cloud = RenderLidarScan(world, SensorAt(Vec3(0, 0, 1.73), 0.0), options, 1);
  int on_wall = 0;
  for (const Vec3& p : cloud.points) {
    ASSERT_GE(p.norm(), options.min_range_m);
    const double azimuth = std::abs(std::atan2(p.y(), p.x())) / kDeg;
    // The near box hides everything behind it, and its own returns are too close.
    ASSERT_GT(azimuth, 13.0) << p.transpose();
    if (azimuth < 60.0) {
      ASSERT_LE(p.x(), 10.0 + 1e-6) << "beyond the wall";
    }
    if (std::abs(p.x() - 10.0) < 1e-6) ++on_wall;
  }
  EXPECT_GT(on_wall, 1000);
}

TEST(LidarScannerTest, SameSeedSamePointsWhateverTheThreads) {
  const TriangleMesh plane = GroundPlane(500.0);
  auto caster = RayCaster::Build(plane);
  ASSERT_TRUE(caster.ok());
  LidarOptions options;
  options.range_noise_sigma_m = 0.03;
  options.dropout_probability = 0.05;
  const Matrix4 pose = SensorAt(Vec3(3, 4, 1.73), 10.0);
  const PointCloud one = RenderLidarScan(**caster, pose, options, 42, 1);
  const PointCloud two = RenderLidarScan(**caster, pose, options, 42, 2);
  EXPECT_EQ(one.points, two.points);
  const PointCloud other = RenderLidarScan(**caster, pose, options, 43, 2);
  EXPECT_NE(one.points, other.points);
  // About 5 % of the returns dropped.
  options.dropout_probability = 0.0;
  const double all = static_cast<double>(RenderLidarScan(**caster, pose, options, 42).size());
  EXPECT_NEAR(one.size() / all, 0.95, 0.01);
}

TEST(LidarScannerTest, TheHdl64eLayoutHasItsTwoBlocks) {
  const std::vector<double> e = HDL64EElevationsDeg();
  ASSERT_EQ(e.size(), 64u);
  EXPECT_DOUBLE_EQ(e[0], 2.0);
  EXPECT_NEAR(e[31], 2.0 - 31.0 / 3.0, 1e-9);  // -8.33
  EXPECT_NEAR(e[32], -8.83, 1e-9);
  EXPECT_NEAR(e[63], -24.33, 1e-9);
  LidarOptions options;
  options.elevations_deg = e;
  EXPECT_TRUE(ValidateLidarOptions(options).ok());
  EXPECT_EQ(BeamElevationsDeg(options), e);
}

TEST(LidarScannerTest, RefusesBadOptionsNamingTheFlag) {
  auto message_of = [](const LidarOptions& o) {
    const absl::Status s = ValidateLidarOptions(o);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    return std::string(s.message());
  };
  EXPECT_TRUE(ValidateLidarOptions(LidarOptions{}).ok());
  LidarOptions o;
  o.beams = 0;
  EXPECT_NE(message_of(o).find("--beams"), std::string::npos);
  o = {};
  o.azimuth_step_deg = 0.05;
  EXPECT_NE(message_of(o).find("--azimuth-step"), std::string::npos);
  o.azimuth_step_deg = 0.5;
  EXPECT_NE(message_of(o).find("--azimuth-step"), std::string::npos);
  o = {};
  o.min_range_m = 90.0;
  EXPECT_NE(message_of(o).find("--min-range"), std::string::npos);
  o = {};
  o.max_range_m = 5000.0;
  EXPECT_NE(message_of(o).find("--max-range"), std::string::npos);
  o = {};
  o.range_noise_sigma_m = -0.01;
  EXPECT_NE(message_of(o).find("--noise-m"), std::string::npos);
  o = {};
  o.elevations_deg = {2.0, 3.0};
  EXPECT_NE(message_of(o).find("elevations"), std::string::npos);
  o = {};
  o.ego_body_center = Vec3(0, 0, 0.3);
  EXPECT_NE(message_of(o).find("ego body"), std::string::npos);
}

TEST(LidarScannerTest, RangeNoiseMovesPointsAlongTheirRays) {
  PointCloud cloud;
  for (int k = 0; k < 20000; ++k) cloud.points.push_back(Vec3(3.0 + k % 7, -2.0, 1.0 + k % 3));
  const PointCloud noisy = AddRangeNoise(cloud, 0.05, 9);
  double sum_squared = 0.0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    ASSERT_LT(noisy.points[i].normalized().cross(cloud.points[i].normalized()).norm(), 1e-12);
    const double d = noisy.points[i].norm() - cloud.points[i].norm();
    sum_squared += d * d;
  }
  EXPECT_NEAR(std::sqrt(sum_squared / cloud.size()), 0.05, 0.005);
  EXPECT_EQ(AddRangeNoise(cloud, 0.0, 9).points, cloud.points);
}

}  // namespace
}  // namespace mlsreg::scan
