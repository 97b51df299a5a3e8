#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "mlsreg/correspondences/correspondence_finders.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/io/intrinsics_sidecar.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

const PinholeIntrinsics kCamera{96, 72, 60.0, 60.0, 47.5, 35.5};

template <typename Depth>
PointCloud Render(Depth depth) {
  return testing::RenderDepthImage(kCamera, depth);
}

TEST(DepthGridTest, PlacesEveryPixelOfARenderedScan) {
  const PointCloud scan = Render([](double, double) { return 2.0; });
  auto grid = DepthGrid::Build(scan.points, *scan.intrinsics);
  ASSERT_TRUE(grid.ok()) << grid.status();
  EXPECT_EQ(grid->At(0, 0), 0);
  EXPECT_EQ(grid->At(kCamera.width - 1, kCamera.height - 1), kCamera.width * kCamera.height - 1);
  EXPECT_EQ(grid->At(-1, 0), -1);
  EXPECT_EQ(grid->At(kCamera.width, 0), -1);
}

TEST(ReverseCalibrationTest, BilinearIsExactOnAFrontoParallelPlane) {
  auto target = Target::Build(Render([](double, double) { return 2.0; }));
  ASSERT_TRUE(target.ok()) << target.status();
  ReverseCalibrationFinder finder(**target, ReverseCalibrationFinder::Interpolation::kBilinear);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> uv(0.0, 1.0), dz(-0.2, 0.2);
  std::vector<Vec3> queries;
  for (int i = 0; i < 200; ++i) {
    const double u = 1 + uv(rng) * (kCamera.width - 3), v = 1 + uv(rng) * (kCamera.height - 3);
    const double z = 2.0 + dz(rng);
    queries.emplace_back((u - kCamera.cx) / kCamera.fx * z, (v - kCamera.cy) / kCamera.fy * z, z);
  }
  std::vector<Correspondence> out(queries.size());
  finder.Find(queries, out);
  for (std::size_t i = 0; i < queries.size(); ++i) {
    ASSERT_TRUE(out[i].valid);
    EXPECT_NEAR(out[i].point.z(), 2.0, 1e-12);
    // On the query's own camera ray: the reverse-calibration correspondence.
    EXPECT_NEAR((out[i].point / out[i].point.z() - queries[i] / queries[i].z()).norm(), 0.0, 1e-12);
    EXPECT_NEAR(std::abs(out[i].normal.z()), 1.0, 1e-9);
  }
}

TEST(ReverseCalibrationTest, BothAreExactOnATiltedPlane) {
  // An affine blend of coplanar samples stays on their plane, and projecting onto that plane's
  // tangent planes changes nothing: both interpolations land exactly on a tilted plane.
  const Vec3 n = Vec3(0.4, -0.3, 1.0).normalized();
  const double c = 2.0 * n.z();
  const PointCloud scan =
      Render([&](double x, double y) { return (c - n.x() * x - n.y() * y) / n.z(); });
  auto target = Target::Build(scan);
  ASSERT_TRUE(target.ok()) << target.status();
  for (auto mode : {ReverseCalibrationFinder::Interpolation::kBilinear,
                    ReverseCalibrationFinder::Interpolation::kPhong}) {
    ReverseCalibrationFinder finder(**target, mode);
    std::vector<Vec3> queries;
    for (int i = 0; i < 100; ++i) {
      queries.push_back(scan.points[(i * 37) % scan.size()] * 1.003 + Vec3(0.0011, -0.0007, 0));
    }
    std::vector<Correspondence> out(queries.size());
    finder.Find(queries, out);
    int valid = 0;
    for (const Correspondence& corr : out) {
      if (!corr.valid) continue;
      ++valid;
      EXPECT_NEAR(n.dot(corr.point), c, 1e-12);
    }
    EXPECT_GT(valid, 80);
  }
}

TEST(ReverseCalibrationTest, PhongFollowsACurvedSurfaceCloserThanBilinear) {
  // A sphere of radius 1 centred 3 in front of the camera: bilinear blends cut the chords inside
  // the sphere; Phong tessellation bends them back toward it (Boubekeur and Alexa 2008).
  const Vec3 centre(0, 0, 3);
  auto depth = [&](double x, double y) {
    const double r2 = x * x + y * y;
    return r2 < 0.81 ? 3.0 - std::sqrt(1.0 - r2) : 3.0;
  };
  auto target = Target::Build(Render(depth));
  ASSERT_TRUE(target.ok()) << target.status();
  ReverseCalibrationFinder phong(**target, ReverseCalibrationFinder::Interpolation::kPhong);
  ReverseCalibrationFinder bilinear(**target, ReverseCalibrationFinder::Interpolation::kBilinear);
  std::vector<Vec3> queries;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> xy(-0.5, 0.5);
  for (int i = 0; i < 300; ++i) {
    const double x = xy(rng), y = xy(rng);
    queries.emplace_back(x, y, depth(x, y));
  }
  std::vector<Correspondence> out_phong(queries.size()), out_bilinear(queries.size());
  phong.Find(queries, out_phong);
  bilinear.Find(queries, out_bilinear);
  double error_phong = 0.0, error_bilinear = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    ASSERT_TRUE(out_phong[i].valid && out_bilinear[i].valid);
    error_phong += std::abs((out_phong[i].point - centre).norm() - 1.0);
    error_bilinear += std::abs((out_bilinear[i].point - centre).norm() - 1.0);
    ++n;
  }
  // Expected: alpha = 3/4 turns the chord's sag s into an overshoot of s / 2.
  EXPECT_LT(error_phong / n, 0.7 * error_bilinear / n);
  // Without the shape factor (alpha = 1) Phong overshoots outward by about as much as bilinear
  // falls short inward: no real gain.
  ReverseCalibrationFinder plain_phong(**target, ReverseCalibrationFinder::Interpolation::kPhong,
                                       1.0);
  std::vector<Correspondence> out_plain(queries.size());
  plain_phong.Find(queries, out_plain);
  double error_plain = 0.0;
  for (const Correspondence& corr : out_plain)
    error_plain += std::abs((corr.point - centre).norm() - 1.0);
  EXPECT_GT(error_plain, 0.8 * error_bilinear);
  EXPECT_LT(error_plain, 1.2 * error_bilinear);
}

class ReverseCalibrationRegistrationTest : public ::testing::TestWithParam<Method> {};

TEST_P(ReverseCalibrationRegistrationTest, RecoversKnownTransformOfARenderedScan) {
  auto depth = [](double x, double y) { return 2.0 + 0.4 * testing::BumpyHeight(x, y); };
  auto target = Target::Build(Render(depth));
  ASSERT_TRUE(target.ok()) << target.status();
  const double d = (*target)->sampling_distance();
  // Source: an independent random sampling of the central part of the same surface.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> coord(-0.5, 0.5);
  const Matrix4 truth = RandomPerturbation(4.0, 4.0 * d, Vec3(0, 0, 2), 6);
  const Matrix4 inverse = truth.inverse();
  PointCloud source;
  for (int i = 0; i < 8000; ++i) {
    const double x = coord(rng), y = coord(rng);
    const Vec3 p(x, y, depth(x, y));
    source.points.push_back(inverse.topLeftCorner<3, 3>() * p + inverse.topRightCorner<3, 1>());
  }
  RegistrationOptions options;
  options.method = GetParam();
  auto result = Register(**target, source, Matrix4::Identity(), options);
  ASSERT_TRUE(result.ok()) << result.status();
  const PoseError e = EvaluatePose(source.points, result->transform, truth, d);
  EXPECT_LT(e.rmse_d, 0.5) << MethodName(GetParam());
  EXPECT_LT(e.rotation_deg, 0.2);
}

INSTANTIATE_TEST_SUITE_P(RcBlAndRcP, ReverseCalibrationRegistrationTest,
                         ::testing::Values(Method::kRcBl, Method::kRcP), [](const auto& info) {
                           return std::string(info.param == Method::kRcBl ? "RcBl" : "RcP");
                         });

TEST(ReverseCalibrationTest, FailsCleanlyWithoutAnOrganisedTarget) {
  auto target = Target::Build(testing::SampleBumpySurface(5000, -1, 1, 1));
  ASSERT_TRUE(target.ok());
  RegistrationOptions options;
  options.method = Method::kRcP;
  auto result = Register(**target, testing::SampleBumpySurface(3000, -0.5, 0.5, 2),
                         Matrix4::Identity(), options);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(result.status().message().find("intrinsics"), std::string::npos);
}

TEST(ReverseCalibrationTest, ReadsTheIntrinsicsSidecar) {
  const std::string dir = ::testing::TempDir() + "/rc_sidecar";
  std::filesystem::create_directories(dir);
  const PointCloud scan = Render([](double, double) { return 2.0; });
  ASSERT_TRUE(WritePointCloud(scan, dir + "/scan.ply").ok());
  std::ofstream(dir + "/scan.ply.intrinsics") << FormatIntrinsics(kCamera);
  auto read = ReadPointCloud(dir + "/scan.ply");
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_TRUE(read->intrinsics.has_value());
  EXPECT_EQ(read->intrinsics->width, kCamera.width);
  EXPECT_DOUBLE_EQ(read->intrinsics->cx, kCamera.cx);
  std::ofstream(dir + "/scan.ply.intrinsics") << "96 72 60 sixty 47.5 35.5\n";
  auto bad = ReadPointCloud(dir + "/scan.ply");
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("'sixty' is not a number"), std::string::npos);
}

}  // namespace
}  // namespace mlsreg
