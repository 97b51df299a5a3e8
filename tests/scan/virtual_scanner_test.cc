// The virtual scanner: rays land on the mesh, scans are in the camera frame, the protocol's
// ground truth maps one view onto its neighbour, noise has the requested size.
#include "scan/virtual_scanner.h"

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "gtest/gtest.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "scan/ray_caster.h"
#include "scan/test_meshes.h"

namespace mlsreg::scan {
namespace {

TEST(RayCasterTest, HitsASquareAtTheRightDistanceWithAFacingNormal) {
  TriangleMesh square;
  square.vertices = {Vec3(-1, -1, 5), Vec3(1, -1, 5), Vec3(1, 1, 5), Vec3(-1, 1, 5)};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  auto caster = RayCaster::Build(square);
  ASSERT_TRUE(caster.ok()) << caster.status();
  const Vec3 direction = Vec3(0.1, 0.05, 1.0).normalized();
  const auto hit = (*caster)->Cast(Vec3::Zero(), direction);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR((hit->distance * direction).z(), 5.0, 1e-12);
  EXPECT_NEAR(hit->normal.z(), -1.0, 1e-12);  // toward the ray's origin
  EXPECT_FALSE((*caster)->Cast(Vec3::Zero(), Vec3(0, 0, -1)).has_value());
  EXPECT_FALSE((*caster)->Cast(Vec3::Zero(), Vec3(1, 0, 0.1).normalized()).has_value());
}

TEST(RayCasterTest, RefusesAnEmptyMesh) { EXPECT_FALSE(RayCaster::Build(TriangleMesh{}).ok()); }

TEST(VirtualScannerTest, ScanOfASphereLiesOnTheSphereInTheCameraFrame) {
  const Vec3 center(0.3, -0.2, 0.1);
  const double radius = 2.0;
  const TriangleMesh mesh = UvSphere(center, radius, 90, 180);
  auto caster = RayCaster::Build(mesh);
  ASSERT_TRUE(caster.ok());
  CameraOptions options;
  options.width = 80;
  options.height = 60;
  const double distance = FramingDistance(radius, options);
  const Camera camera = CircleCamera(center, distance, 90.0, options);
  const Scan scan = RenderScan(**caster, camera);
  ASSERT_GT(scan.cloud.size(), 1000u);
  // The camera looks at the center: in its frame the sphere is centred on +z at `distance`.
  const Vec3 center_camera(0, 0, distance);
  for (std::size_t i = 0; i < scan.cloud.size(); ++i) {
    const double r = (scan.cloud.points[i] - center_camera).norm();
    ASSERT_NEAR(r, radius, 2e-3 * radius) << "point " << i;  // the tessellation's sagitta
    // Visible side only: the normal faces the camera.
    ASSERT_LT(scan.surface_normals[i].dot(scan.cloud.points[i]), 0.0);
  }
  // Every point sits on its own pixel's ray.
  const PinholeIntrinsics& k = *scan.cloud.intrinsics;
  for (std::size_t i = 0; i < scan.cloud.size(); i += 97) {
    const Vec3& p = scan.cloud.points[i];
    const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
    EXPECT_NEAR(u, scan.pixels[i] % k.width, 1e-6);
    EXPECT_NEAR(v, scan.pixels[i] / k.width, 1e-6);
  }
  // World +y is up, the camera's y points down.
  EXPECT_NEAR(camera.camera_to_world(1, 1), -1.0, 1e-12);
}

TEST(VirtualScannerTest, NoiseMovesPointsAlongNormalsWithTheRequestedSpread) {
  const TriangleMesh mesh = UvSphere(Vec3::Zero(), 1.0, 60, 120);
  auto caster = RayCaster::Build(mesh);
  ASSERT_TRUE(caster.ok());
  const Scan clean = RenderScan(**caster, CircleCamera(Vec3::Zero(), 4.0, 0.0, CameraOptions{}));
  const double sigma = 0.01;
  const Scan noisy = AddNormalNoise(clean, sigma, 7);
  double sum_squared = 0.0;
  for (std::size_t i = 0; i < clean.cloud.size(); ++i) {
    const Vec3 offset = noisy.cloud.points[i] - clean.cloud.points[i];
    ASSERT_LT(offset.cross(clean.surface_normals[i]).norm(), 1e-12);  // along the normal
    sum_squared += offset.squaredNorm();
  }
  EXPECT_NEAR(std::sqrt(sum_squared / clean.cloud.size()), sigma, 0.05 * sigma);
  EXPECT_EQ(AddNormalNoise(clean, sigma, 7).cloud.points, noisy.cloud.points);  // seeded
}

TEST(VirtualScannerTest, ProtocolGroundTruthMapsEachViewOntoTheMesh) {
  // The ground truth must bring the source points of view i+1 onto the sphere as seen from
  // view i, in that camera's frame.
  const Vec3 center(1.0, 2.0, 3.0);
  const TriangleMesh mesh = UvSphere(center, 1.5, 60, 120);
  const std::string out = ::testing::TempDir() + "/scan_protocol";
  std::filesystem::remove_all(out);
  ProtocolOptions options;
  options.views = 6;
  options.noise_sigmas_d = {0.0, 2.0};
  options.camera.width = 96;
  options.camera.height = 72;
  const auto summary = WriteScanProtocol(mesh, "sphere", out, options);
  ASSERT_TRUE(summary.ok()) << summary.status();
  ASSERT_EQ(summary->manifests.size(), 2u);
  EXPECT_GT(summary->sampling_distance, 0.0);

  const auto manifest = ReadManifest(summary->manifests[0]);
  ASSERT_TRUE(manifest.ok()) << manifest.status();
  ASSERT_EQ(manifest->problems.size(), 6u);
  for (const ManifestProblem& problem : manifest->problems) {
    ASSERT_TRUE(problem.ground_truth && problem.initial);
    EXPECT_TRUE(problem.initial->isIdentity());
    const auto source = ReadPointCloud(problem.source_path);
    const auto target = ReadPointCloud(problem.target_path);
    ASSERT_TRUE(source.ok() && target.ok());
    ASSERT_TRUE(target->intrinsics.has_value());  // the sidecar was written and read back
    // In the target camera's frame the sphere's centre is at (0, 0, distance).
    const Vec3 barycenter = mesh.SurfaceCentroid();
    ASSERT_LT((barycenter - center).norm(), 1e-3);
    const Vec3 center_target(0, 0,
                             FramingDistance(mesh.BoundingRadius(barycenter), options.camera));
    const Matrix4& gt = *problem.ground_truth;
    for (std::size_t i = 0; i < source->size(); i += 53) {
      const Vec3 p = gt.topLeftCorner<3, 3>() * source->points[i] + gt.topRightCorner<3, 1>();
      ASSERT_NEAR((p - center_target).norm(), 1.5, 5e-3) << problem.id;
    }
    // The views are 60 degrees apart around the vertical axis.
    const Eigen::AngleAxisd rotation(Eigen::Matrix3d(gt.topLeftCorner<3, 3>()));
    EXPECT_NEAR(rotation.angle() * 180.0 / std::numbers::pi, 60.0, 1e-9);
  }
  EXPECT_TRUE(std::filesystem::exists(out + "/sphere/sigma2/view_060.depth.pfm"));
  std::filesystem::remove_all(out);
}

TEST(VirtualScannerTest, ProtocolRefusesBadOptions) {
  const TriangleMesh mesh = UvSphere(Vec3::Zero(), 1.0, 10, 20);
  ProtocolOptions options;
  options.views = 1;
  EXPECT_EQ(WriteScanProtocol(mesh, "x", ::testing::TempDir(), options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options.views = 4;
  options.noise_sigmas_d = {-1.0};
  EXPECT_EQ(WriteScanProtocol(mesh, "x", ::testing::TempDir(), options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlsreg::scan
