#include "mlsreg/geometry/mls_projector.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mlsreg/geometry/height_field_fit.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/sampling.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

using testing::SamplePlaneGrid;
using testing::SampleSphere;

MlsOptions OptionsWithRadius(double radius) {
  MlsOptions o;
  o.radius = radius;
  return o;
}

TEST(WendlandHeightFieldTest, CubicFitReproducesCubicExactly) {
  HeightFieldFit fit(3);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  auto f = [](double x, double y) {
    return 0.1 + 0.2 * x - 0.3 * y + 0.4 * x * x - 0.5 * x * y + 0.6 * y * y + 0.7 * x * x * x -
           0.1 * x * x * y + 0.2 * x * y * y - 0.3 * y * y * y;
  };
  for (int i = 0; i < 50; ++i) {
    const double x = u(rng), y = u(rng);
    fit.Add(x, y, f(x, y), 0.5 + 0.5 * u(rng) + 0.5);
  }
  HeightField h;
  ASSERT_TRUE(fit.Finalize(h));
  EXPECT_EQ(h.degree, 3);
  EXPECT_NEAR(h.ValueAtOrigin(), 0.1, 1e-9);
  EXPECT_NEAR(h.SlopeX(), 0.2, 1e-9);
  EXPECT_NEAR(h.SlopeY(), -0.3, 1e-9);
  EXPECT_NEAR(h.Evaluate(0.5, -0.25), f(0.5, -0.25), 1e-9);
}

TEST(WendlandHeightFieldTest, FallsBackToLowerDegreeWithFewSamples) {
  HeightFieldFit fit(3);
  // 8 equally weighted samples of f = 1 + x + 2y: enough for a plane (3 coefficients, needs an
  // effective sample size of 6), not for a quadratic (6 coefficients, needs 12).
  for (int i = 0; i < 8; ++i) {
    const double x = i % 3, y = i / 3;
    fit.Add(x, y, 1.0 + x + 2.0 * y, 1.0);
  }
  HeightField h;
  ASSERT_TRUE(fit.Finalize(h));
  EXPECT_EQ(h.degree, 1);
  EXPECT_NEAR(h.ValueAtOrigin(), 1.0, 1e-12);
  EXPECT_NEAR(h.SlopeX(), 1.0, 1e-12);
  EXPECT_NEAR(h.SlopeY(), 2.0, 1e-12);
}

TEST(MlsProjectorTest, ProjectsOntoPlaneExactly) {
  const PointCloud plane = SamplePlaneGrid(1.0, 0.05, 0.02, 7);
  const KdTree tree(plane.points);
  const MlsProjector projector(plane.points, tree, OptionsWithRadius(0.25));
  MlsProjector::Workspace ws;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  for (int i = 0; i < 200; ++i) {
    const Vec3 query(u(rng), u(rng), 0.2 * u(rng));
    const MlsProjection p = projector.Project(query, ws);
    ASSERT_EQ(p.status, ProjectionStatus::kOk) << ProjectionStatusName(p.status);
    EXPECT_NEAR(p.point.z(), 0.0, 1e-9);
    // The projection is orthogonal for a plane: x and y are kept.
    EXPECT_NEAR(p.point.x(), query.x(), 1e-9);
    EXPECT_NEAR(p.point.y(), query.y(), 1e-9);
    EXPECT_NEAR(std::abs(p.normal.z()), 1.0, 1e-9);
    EXPECT_LT(p.curvature, 1e-12);
  }
}

TEST(MlsProjectorTest, ProjectsOntoSphereWithinTolerance) {
  // Radius-1 sphere sampled with d ~ 0.03; MLS radius 5d. A cubic MLS fit reproduces the sphere
  // to far below the sampling distance: we require |p| = 1 within 1e-3 (0.03 d).
  const PointCloud sphere = SampleSphere(20000, 1.0, -2.0, 5);
  const KdTree tree(sphere.points);
  const double d = SamplingDistance(sphere.points, tree);
  ASSERT_GT(d, 0.005);
  ASSERT_LT(d, 0.05);
  const MlsProjector projector(sphere.points, tree, OptionsWithRadius(5.0 * d));
  MlsProjector::Workspace ws;
  std::mt19937_64 rng(13);
  std::normal_distribution<double> g(0.0, 1.0);
  double worst = 0.0;
  for (int i = 0; i < 300; ++i) {
    const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
    // Within 2 d of the surface: the regime where Algorithm 1 starts at the query itself.
    const Vec3 query = dir * (1.0 + 2.0 * d * std::uniform_real_distribution<double>(-1, 1)(rng));
    const MlsProjection p = projector.Project(query, ws);
    ASSERT_EQ(p.status, ProjectionStatus::kOk);
    worst = std::max(worst, std::abs(p.point.norm() - 1.0));
    // The normal is radial.
    EXPECT_GT(std::abs(p.normal.dot(p.point.normalized())), 0.999);
    // Close to the radial projection of the query (the projection is nearly orthogonal).
    EXPECT_LT((p.point - dir).norm(), 0.1 * d);
  }
  EXPECT_LT(worst, 1e-3);
}

TEST(MlsProjectorTest, ProjectsOntoParaboloidWithinTolerance) {
  // z = 0.5 (x^2 + y^2), curvature 1 at the apex; grid spacing 0.02, r = 5d.
  PointCloud cloud;
  for (double x = -1; x <= 1; x += 0.02) {
    for (double y = -1; y <= 1; y += 0.02) cloud.points.emplace_back(x, y, 0.5 * (x * x + y * y));
  }
  const KdTree tree(cloud.points);
  const double d = SamplingDistance(cloud.points, tree);
  const MlsProjector projector(cloud.points, tree, OptionsWithRadius(5.0 * d));
  MlsProjector::Workspace ws;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  for (int i = 0; i < 200; ++i) {
    const double x = u(rng), y = u(rng);
    const Vec3 query(x, y, 0.5 * (x * x + y * y) + 0.02 * u(rng));
    const MlsProjection p = projector.Project(query, ws);
    ASSERT_EQ(p.status, ProjectionStatus::kOk);
    const double surface_z = 0.5 * (p.point.x() * p.point.x() + p.point.y() * p.point.y());
    EXPECT_NEAR(p.point.z(), surface_z, 2e-5);  // 1e-3 d
    const Vec3 true_normal = Vec3(-p.point.x(), -p.point.y(), 1.0).normalized();
    EXPECT_GT(std::abs(p.normal.dot(true_normal)), 0.99999);
  }
}

TEST(MlsProjectorTest, DenoisesNoisyPlane) {
  // Noise sigma = 0.8 d along the normal; projections must land much closer to the true plane
  // than the samples themselves (paper section 4: the MLS surface is de-noised).
  const double spacing = 0.02;
  const PointCloud noisy = SamplePlaneGrid(1.0, spacing, 0.005, 19, /*noise=*/0.8 * spacing);
  const KdTree tree(noisy.points);
  const double d = SamplingDistance(noisy.points, tree);
  const MlsProjector projector(noisy.points, tree, OptionsWithRadius(8.0 * d));
  MlsProjector::Workspace ws;
  double sample_sq = 0.0, projected_sq = 0.0;
  int n = 0;
  for (const Vec3& q : noisy.points) {
    if (std::abs(q.x()) > 0.7 || std::abs(q.y()) > 0.7) continue;  // away from the border
    const MlsProjection p = projector.Project(q, ws);
    ASSERT_EQ(p.status, ProjectionStatus::kOk);
    sample_sq += q.z() * q.z();
    projected_sq += p.point.z() * p.point.z();
    ++n;
  }
  const double sample_rms = std::sqrt(sample_sq / n);
  const double projected_rms = std::sqrt(projected_sq / n);
  EXPECT_NEAR(sample_rms, 0.8 * spacing, 0.1 * spacing);
  EXPECT_LT(projected_rms, 0.25 * sample_rms);
}

TEST(MlsProjectorTest, FarQueryIsSeededFromNearestSampleOrRejected) {
  const PointCloud plane = SamplePlaneGrid(1.0, 0.05, 0.0, 1);
  const KdTree tree(plane.points);
  MlsOptions options = OptionsWithRadius(0.2);
  MlsProjector::Workspace ws;
  const Vec3 far_query(0.1, 0.1, 5.0);
  {
    const MlsProjector projector(plane.points, tree, options);
    const MlsProjection p = projector.Project(far_query, ws);
    ASSERT_EQ(p.status, ProjectionStatus::kOk);
    EXPECT_NEAR(p.point.z(), 0.0, 1e-9);
  }
  options.seed_far_queries_from_nearest_sample = false;
  const MlsProjector strict(plane.points, tree, options);
  const MlsProjection p = strict.Project(far_query, ws);
  EXPECT_EQ(p.status, ProjectionStatus::kTooFewNeighbors);
  EXPECT_TRUE(p.point.allFinite());
  EXPECT_TRUE(p.normal.allFinite());
}

TEST(MlsProjectorTest, CollinearSamplesAreDegenerateNotNan) {
  PointCloud line;
  for (int i = 0; i < 100; ++i) line.points.emplace_back(0.01 * i, 0.0, 0.0);
  const KdTree tree(line.points);
  const MlsProjector projector(line.points, tree, OptionsWithRadius(0.1));
  MlsProjector::Workspace ws;
  const MlsProjection p = projector.Project(Vec3(0.5, 0.01, 0.0), ws);
  EXPECT_EQ(p.status, ProjectionStatus::kDegenerate);
  EXPECT_TRUE(p.point.allFinite());
  EXPECT_TRUE(p.normal.allFinite());
}

// Rings of a scan on flat ground, 2 cm apart along each ring and 0.3 m between rings: a support
// of r = 0.1 holds one ring (a line: ProjectUnlessLine gives up after the first PCA, and Project
// ends in a fit whose middle spread is as small), one of r = 0.5 several (a plane: the same
// projection as Project, bit for bit). On a sphere every projection is Project's.
TEST(MlsProjectorTest, ProjectUnlessLineGivesUpOnOneRingAndIsProjectElsewhere) {
  PointCloud rings;
  for (int ring = 0; ring < 8; ++ring) {
    for (int i = 0; i < 100; ++i) {
      rings.points.emplace_back(0.02 * i, 0.3 * ring, 0.001 * std::sin(0.7 * i + ring));
    }
  }
  const KdTree tree(rings.points);
  const Vec3 query(1.0, 0.9, 0.05);  // above the fourth ring
  MlsProjector::Workspace ws;
  const MlsProjector narrow(rings.points, tree, OptionsWithRadius(0.1));
  EXPECT_EQ(narrow.ProjectUnlessLine(query, ws, 0.05).status, ProjectionStatus::kLineSupport);
  const MlsProjection full = narrow.Project(query, ws);
  if (full.status == ProjectionStatus::kOk) {
    const Vec3& spread = ws.last_fit.frame.eigenvalues;
    EXPECT_LT(spread[1], 0.05 * spread[2]);
  }
  const auto expect_same = [&](const MlsProjector& projector, const Vec3& q) {
    const MlsProjection want = projector.Project(q, ws);
    const MlsProjection got = projector.ProjectUnlessLine(q, ws, 0.05);
    ASSERT_EQ(got.status, want.status);
    EXPECT_EQ(got.point, want.point);
    EXPECT_EQ(got.normal, want.normal);
    EXPECT_EQ(got.iterations, want.iterations);
  };
  const MlsProjector wide(rings.points, tree, OptionsWithRadius(0.5));
  ASSERT_EQ(wide.Project(query, ws).status, ProjectionStatus::kOk);
  expect_same(wide, query);
  const PointCloud sphere = SampleSphere(5000, 1.0, -2.0, 5);
  const KdTree sphere_tree(sphere.points);
  const MlsProjector on_sphere(
      sphere.points, sphere_tree,
      OptionsWithRadius(5.0 * SamplingDistance(sphere.points, sphere_tree)));
  for (int i = 0; i < 50; ++i) expect_same(on_sphere, 1.01 * sphere.points[i * 97]);
}

TEST(MlsProjectorTest, WarmStartOnTangentPlaneAgreesWithColdStart) {
  const PointCloud sphere = SampleSphere(20000, 1.0, -2.0, 23);
  const KdTree tree(sphere.points);
  const double d = SamplingDistance(sphere.points, tree);
  const MlsProjector projector(sphere.points, tree, OptionsWithRadius(5.0 * d));
  MlsProjector::Workspace ws;
  std::mt19937_64 rng(29);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
    const Vec3 query = dir * (1.0 + d * g(rng));
    const MlsProjection previous = projector.Project(dir * 1.0 + Vec3(d, 0, 0) * 0.5, ws);
    ASSERT_EQ(previous.status, ProjectionStatus::kOk);
    const Vec3 start = query - (query - previous.point).dot(previous.normal) * previous.normal;
    const MlsProjection warm = projector.ProjectFrom(start, ws);
    const MlsProjection cold = projector.Project(query, ws);
    ASSERT_EQ(warm.status, ProjectionStatus::kOk);
    EXPECT_LT((warm.point - cold.point).norm(), 0.05 * d);
    EXPECT_LE(warm.iterations, cold.iterations + 1);
  }
}

// A query walking slowly over a sphere (as a sample does in ICP's fine phase) keeps its
// neighbourhood: the projection matches the one that searches the tree each time to rounding, the
// neighbourhood is gathered again only after the walk left its margin, and the point lands on the
// sphere.
TEST(MlsProjectorTest, KeptNeighborhoodGivesTheSameProjectionWithFewerSearches) {
  const PointCloud sphere = SampleSphere(20000, 1.0, -2.0, 31);
  const KdTree tree(sphere.points);
  const double d = SamplingDistance(sphere.points, tree);
  const double r = 5.0 * d;
  const MlsProjector projector(sphere.points, tree, OptionsWithRadius(r));
  MlsProjector::Workspace ws;
  KeptNeighborhood kept;
  // 200 steps of 0.02 r along a great circle, 0.05 d off the surface (where a warm start lies).
  const double step = 0.02 * r;
  int gathers = 0;
  Vec3 last_center = Vec3::Constant(1e9);
  for (int i = 0; i < 200; ++i) {
    const double angle = i * step;
    const Vec3 query = (1.0 + 0.05 * d) * Vec3(std::cos(angle), std::sin(angle), 0.0);
    const MlsProjection with_kept = projector.ProjectFrom(query, ws, &kept);
    const MlsProjection searched = projector.ProjectFrom(query, ws);
    ASSERT_EQ(with_kept.status, ProjectionStatus::kOk);
    ASSERT_EQ(searched.status, ProjectionStatus::kOk);
    EXPECT_LT((with_kept.point - searched.point).norm(), 1e-12);
    EXPECT_GT(with_kept.normal.dot(searched.normal), 1.0 - 1e-12);
    EXPECT_NEAR(with_kept.point.norm(), 1.0, 1e-3);
    if ((kept.center - last_center).norm() > 0.0) ++gathers;
    last_center = kept.center;
    // Every sample in the support of the projected point is in the kept neighbourhood.
    EXPECT_LE((with_kept.point - kept.center).norm() + r, kept.reach * (1.0 + 1e-12));
  }
  // The walk covers 4 r; a margin of 0.1 r lasts about 5 steps (the gather's centre is the
  // first iterate, so a step can use up to twice its length of the margin).
  EXPECT_LE(gathers, 200 / 2);
  EXPECT_GE(gathers, 200 / 10);
}

}  // namespace
}  // namespace mlsreg
