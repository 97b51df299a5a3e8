// EstimateNoise recovers the noise the virtual scanner adds along the surface normals, on a
// sphere and on the Stanford bunny's reconstruction, from noise-free to 4 d.
#include "mlsreg/geometry/noise_estimate.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "gtest/gtest.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/io/mesh_io.h"
#include "scan/ray_caster.h"
#include "scan/test_meshes.h"
#include "scan/virtual_scanner.h"

namespace mlsreg::scan {
namespace {

// Stated tolerance: within 15 % of the added sigma plus 0.15 d (the residual of a quadric on a
// noise-free but tessellated, unevenly sampled surface).
void ExpectRecoversAddedNoise(const TriangleMesh& mesh, const Vec3& center, double radius) {
  auto caster = RayCaster::Build(mesh);
  ASSERT_TRUE(caster.ok());
  const CameraOptions camera;
  const Scan clean =
      RenderScan(**caster, CircleCamera(center, FramingDistance(radius, camera), 30.0, camera));
  ASSERT_GT(clean.cloud.size(), 10000u);
  const KdTree clean_tree(clean.cloud.points);
  const double d = SamplingDistance(clean.cloud.points, clean_tree);
  for (double sigma_d : {0.0, 0.8, 2.0, 4.0}) {
    SCOPED_TRACE(testing::Message() << "sigma = " << sigma_d << " d");
    const Scan noisy = AddNormalNoise(clean, sigma_d * d, 11);
    const KdTree tree(noisy.cloud.points);
    const double noisy_d = SamplingDistance(noisy.cloud.points, tree);
    const NoiseEstimate estimate = EstimateNoise(noisy.cloud.points, tree, noisy_d);
    ASSERT_GT(estimate.probes, 100);
    std::printf("added %.2f d, estimated %.3f d (clean d), fit radius %.1f d, %d probes\n", sigma_d,
                estimate.sigma_d * noisy_d / d, estimate.fit_radius_d, estimate.probes);
    // The estimate is in units of the noisy cloud's own d; compare absolute lengths.
    EXPECT_NEAR(estimate.sigma_d * noisy_d, sigma_d * d, 0.15 * sigma_d * d + 0.15 * d)
        << "estimated " << estimate.sigma_d * noisy_d / d << " d (clean d), fit radius "
        << estimate.fit_radius_d << " d";
  }
}

TEST(NoiseEstimateTest, RecoversTheScannersNoiseOnASphere) {
  ExpectRecoversAddedNoise(UvSphere(Vec3::Zero(), 1.0, 180, 360), Vec3::Zero(), 1.0);
}

TEST(NoiseEstimateTest, RecoversTheScannersNoiseOnTheBunny) {
  const std::filesystem::path path = std::filesystem::path(MLSREG_SHARED_DATA_DIR) /
                                     "stanford_bunny/reconstruction/bun_zipper.ply";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is not here";
  auto mesh = ReadTriangleMesh(path.string());
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  Vec3 lo = mesh->vertices[0], hi = lo;
  for (const Vec3& v : mesh->vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  ExpectRecoversAddedNoise(*mesh, (lo + hi) / 2, (hi - lo).norm() / 2);
}

}  // namespace
}  // namespace mlsreg::scan
