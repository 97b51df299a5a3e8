// Multi-view alignment: the pose graph on its own (exact rings, a corrupted edge), AlignScans on
// a synthetic ring of views of a bumpy closed surface, cancellation and bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <numbers>
#include <random>

#include "mlsreg/geometry/target.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/multiview/merged_cloud.h"
#include "mlsreg/multiview/pose_graph.h"

namespace mlsreg {
namespace {

constexpr double kPi = std::numbers::pi;

Matrix4 Pose(double yaw, const Vec3& t, const Vec3& axis = Vec3::UnitY()) {
  Matrix4 m = Matrix4::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(yaw, axis.normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

double RotationErrorDeg(const Matrix4& a, const Matrix4& b) {
  const Eigen::Matrix3d r = a.topLeftCorner<3, 3>().transpose() * b.topLeftCorner<3, 3>();
  return Eigen::AngleAxisd(r).angle() * 180.0 / kPi;
}

double TranslationError(const Matrix4& a, const Matrix4& b) {
  return (a.topRightCorner<3, 1>() - b.topRightCorner<3, 1>()).norm();
}

// ---- the pose graph

std::vector<Matrix4> RingPoses(int n) {
  std::vector<Matrix4> poses;
  for (int i = 0; i < n; ++i) {
    poses.push_back(Pose(2 * kPi * i / n, Vec3(std::cos(i), 0.1 * i, std::sin(0.5 * i))));
  }
  return poses;
}

std::vector<PoseGraphEdge> ExactRingEdges(const std::vector<Matrix4>& truth) {
  const int n = static_cast<int>(truth.size());
  Matrix6 information = Matrix6::Identity();
  information.topLeftCorner<3, 3>() *= 1e4;  // rotation: a radian moves points by ~100 d
  std::vector<PoseGraphEdge> edges;
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    edges.push_back({.from = i,
                     .to = j,
                     .measurement = truth[i].inverse() * truth[j],
                     .information = information});
  }
  return edges;
}

TEST(PoseGraphTest, ExactMeasurementsGiveTheTruthFromAPerturbedStart) {
  const std::vector<Matrix4> truth = RingPoses(8);
  std::vector<Matrix4> start = truth;
  for (int i = 1; i < 8; ++i) start[i] = Pose(0.1 * i, Vec3(0.2, -0.1, 0.05 * i)) * truth[i];
  auto result = OptimisePoseGraph(start, ExactRingEdges(truth));
  ASSERT_TRUE(result.ok()) << result.status();
  for (int i = 0; i < 8; ++i) {
    EXPECT_LT(RotationErrorDeg(result->poses[i], truth[i]), 1e-6) << i;
    EXPECT_LT(TranslationError(result->poses[i], truth[i]), 1e-7) << i;
  }
  for (std::size_t e = 0; e < 8; ++e) {
    EXPECT_TRUE(result->kept[e]);
    EXPECT_LT(result->residual_after_d[e], 1e-6);
  }
}

TEST(PoseGraphTest, ACorruptedEdgeIsDroppedAndTheOthersGiveTheTruth) {
  const std::vector<Matrix4> truth = RingPoses(8);
  std::vector<PoseGraphEdge> edges = ExactRingEdges(truth);
  // One more edge per pose pair (i, i+2), so that dropping any single edge keeps the graph whole.
  for (int i = 0; i < 8; ++i) {
    const int j = (i + 2) % 8;
    edges.push_back({.from = i,
                     .to = j,
                     .measurement = truth[i].inverse() * truth[j],
                     .information = edges[0].information});
  }
  edges[3].measurement = Pose(20.0 * kPi / 180.0, Vec3(0.3, 0, 0), Vec3(1, 1, 0)) *
                         edges[3].measurement;  // 20 degrees and 0.3 off
  std::vector<Matrix4> start = truth;
  for (int i = 1; i < 8; ++i) start[i] = Pose(0.05 * i, Vec3(0.05, 0, 0)) * truth[i];
  auto result = OptimisePoseGraph(start, edges);
  ASSERT_TRUE(result.ok()) << result.status();
  for (std::size_t e = 0; e < edges.size(); ++e) EXPECT_EQ(result->kept[e], e != 3) << e;
  EXPECT_GT(result->residual_after_d[3], 10.0);
  for (int i = 0; i < 8; ++i) {
    EXPECT_LT(RotationErrorDeg(result->poses[i], truth[i]), 1e-5) << i;
    EXPECT_LT(TranslationError(result->poses[i], truth[i]), 1e-6) << i;
  }
}

TEST(PoseGraphTest, AnEdgeThatIsTheOnlyLinkIsKeptEvenWhenItDisagrees) {
  const std::vector<Matrix4> truth = RingPoses(4);
  std::vector<PoseGraphEdge> edges = ExactRingEdges(truth);
  edges.pop_back();  // a chain 0-1-2-3: every edge is a bridge
  edges[1].measurement = Pose(0.5, Vec3(1, 0, 0)) * edges[1].measurement;
  auto result = OptimisePoseGraph(truth, edges);
  ASSERT_TRUE(result.ok());
  for (bool kept : result->kept) EXPECT_TRUE(kept);
}

// A triangle of translations: 0 at the origin, 1 ten along x, 2 ten along x and y. The edge
// (0, 1) is 0.5 off along x, a direction its covariance says it barely knows (a bare road);
// the edges (1, 2) and (0, 2) are exact and certain. Each measurement is good to 0.01 elsewhere.
struct UncertainTriangle {
  std::vector<Matrix4> truth{Pose(0, Vec3::Zero()), Pose(0, Vec3(10, 0, 0)),
                             Pose(0, Vec3(10, 10, 0))};
  std::vector<PoseGraphEdge> edges;
  UncertainTriangle() {
    Matrix6 certain = Matrix6::Identity() * 1e-4;  // 0.01 rad and 0.01 per direction
    Matrix6 slides_along_x = certain;
    slides_along_x(3, 3) = 1.0;  // translation x: 1 sigma = 1
    const auto edge = [&](int i, int j) { return truth[i].inverse() * truth[j]; };
    edges.push_back(
        {0, 1, Pose(0, Vec3(0.5, 0, 0)) * edge(0, 1), Matrix6::Identity(), slides_along_x});
    edges.push_back({1, 2, edge(1, 2), Matrix6::Identity(), certain});
    edges.push_back({0, 2, edge(0, 2), Matrix6::Identity(), certain});
  }
};

TEST(PoseGraphTest, TheFinalSolveTrustsEachEdgeAlongTheDirectionsItsCovarianceFixes) {
  const UncertainTriangle triangle;
  auto weighed = OptimisePoseGraph(triangle.truth, triangle.edges);
  ASSERT_TRUE(weighed.ok()) << weighed.status();
  EXPECT_EQ(weighed->covariance_weighted, 3);
  for (bool kept : weighed->kept) EXPECT_TRUE(kept);  // 0.5 disagrees less than reject_above_d
  // The certain edges fix pose 1 along x: the 0.5 of edge (0, 1) moves it by 0.5 * 1e-4 / (1 +
  // 2e-4) at most.
  for (int i = 0; i < 3; ++i)
    EXPECT_LT(TranslationError(weighed->poses[i], triangle.truth[i]), 1e-3);

  // Weighed by `information` alone (equal for all three), the 0.5 spreads over the loop.
  PoseGraphOptions options;
  options.weigh_by_covariance = false;
  auto unweighed = OptimisePoseGraph(triangle.truth, triangle.edges, options);
  ASSERT_TRUE(unweighed.ok());
  EXPECT_EQ(unweighed->covariance_weighted, 0);
  EXPECT_GT(TranslationError(unweighed->poses[1], triangle.truth[1]), 0.1);
}

// Exact edges, each with rotation variance 1e-6 rad^2 and translation variance 1e-2 per axis: the
// poses' covariances follow the graph's paths (a lever of 1 adds only 1e-6 to a translation).
std::vector<PoseGraphEdge> EdgesWithCovariance(const std::vector<Matrix4>& truth,
                                               const std::vector<std::pair<int, int>>& pairs) {
  Matrix6 covariance = Matrix6::Identity() * 1e-2;
  covariance.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() * 1e-6;
  std::vector<PoseGraphEdge> edges;
  for (const auto& [i, j] : pairs) {
    edges.push_back({.from = i,
                     .to = j,
                     .measurement = truth[i].inverse() * truth[j],
                     .covariance = covariance});
  }
  return edges;
}

TEST(PoseGraphTest, PoseCovariancesAddAlongAChainCombineOverParallelPathsAndCountSharedScans) {
  const std::vector<Matrix4> truth{Pose(0, Vec3::Zero()), Pose(0, Vec3(1, 0, 0)),
                                   Pose(0, Vec3(2, 0, 0))};
  const auto expect_near = [](const Matrix6& actual, double rotation, double translation,
                              const char* what) {
    Matrix6 expected = Matrix6::Identity() * translation;
    expected.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() * rotation;
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) {
        const double scale = r < 3 && c < 3 ? rotation : translation;
        EXPECT_NEAR(actual(r, c), expected(r, c), 0.02 * scale)
            << what << " (" << r << ", " << c << ")";
      }
    }
  };
  // The solve's own covariance: the edges taken as independent.
  PoseGraphOptions independent;
  independent.shared_scan_noise = 0.0;
  // A chain 0 - 1 - 2: pose 1 is as uncertain as one edge, pose 2 as two.
  auto chain = OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}, {1, 2}}), independent);
  ASSERT_TRUE(chain.ok()) << chain.status();
  ASSERT_EQ(chain->pose_covariances.size(), 3u);
  EXPECT_FALSE(chain->pose_covariances[0].has_value());  // the anchor
  ASSERT_TRUE(chain->pose_covariances[1] && chain->pose_covariances[2]);
  expect_near(*chain->pose_covariances[1], 1e-6, 1e-2, "chain, pose 1");
  expect_near(*chain->pose_covariances[2], 2e-6, 2e-2, "chain, pose 2");
  EXPECT_NEAR(SigmasOf(*chain->pose_covariances[2]).translation, std::sqrt(2e-2), 1e-3);
  EXPECT_NEAR(SigmasOf(*chain->pose_covariances[2]).rotation_deg, std::sqrt(2e-6) * 180 / kPi,
              1e-3);

  // A loop 0 - 1 - 2 - 0: pose 1 hears one edge directly and two through pose 2, so its variance
  // is 1 * 2 / (1 + 2) of one edge's.
  auto loop =
      OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}, {1, 2}, {2, 0}}), independent);
  ASSERT_TRUE(loop.ok()) << loop.status();
  ASSERT_TRUE(loop->pose_covariances[1]);
  expect_near(*loop->pose_covariances[1], 2e-6 / 3, 2e-2 / 3, "loop, pose 1");

  // By default each edge counts the noise it shares with the edges sharing its scans: in the
  // chain both edges share scan 1 with one other (inflation 1 + 1/4), in the loop every edge
  // shares each of its scans with one other (1 + 2/4). The poses are the same.
  auto shared_chain = OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}, {1, 2}}));
  ASSERT_TRUE(shared_chain.ok() && shared_chain->pose_covariances[2]);
  expect_near(*shared_chain->pose_covariances[2], 1.25 * 2e-6, 1.25 * 2e-2, "shared chain, pose 2");
  EXPECT_TRUE(shared_chain->poses == chain->poses);
  auto shared_loop = OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}, {1, 2}, {2, 0}}));
  ASSERT_TRUE(shared_loop.ok() && shared_loop->pose_covariances[1]);
  expect_near(*shared_loop->pose_covariances[1], 1.5 * 2e-6 / 3, 1.5 * 2e-2 / 3,
              "shared loop, pose 1");
  PoseGraphOptions beyond;
  beyond.shared_scan_noise = 1.5;
  const auto refused = OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}}), beyond);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(refused.status().message()).find("shared_scan_noise"), std::string::npos)
      << refused.status();

  // Weighed by information alone the final solve's covariance would be in units of d: none.
  PoseGraphOptions options;
  options.weigh_by_covariance = false;
  auto unweighed = OptimisePoseGraph(truth, EdgesWithCovariance(truth, {{0, 1}, {1, 2}}), options);
  ASSERT_TRUE(unweighed.ok());
  for (const auto& c : unweighed->pose_covariances) EXPECT_FALSE(c.has_value());
}

TEST(PoseGraphTest, AnEdgeWithoutCovarianceIsWeighedLikeItsNeighboursInformation) {
  UncertainTriangle triangle;
  // Edge (1, 2) loses its covariance; its `information` (1 per unit twist) is rescaled by the
  // others' ratio (1e4: trace(covariance * information) = 6e-4 on edge (0, 2)), so it stays as
  // certain as they are, and the x error of edge (0, 1) still goes nowhere.
  triangle.edges[1].covariance.reset();
  auto result = OptimisePoseGraph(triangle.truth, triangle.edges);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->covariance_weighted, 2);
  EXPECT_LT(TranslationError(result->poses[1], triangle.truth[1]), 1e-3);
  EXPECT_LT(TranslationError(result->poses[2], triangle.truth[2]), 1e-3);
}

// ---- AlignScans on a ring of views

// A closed, bumpy, non-symmetric surface: an ellipsoid whose radius carries bumps of several
// frequencies, so that every partial view pins all six degrees of freedom.
Vec3 SurfacePoint(const Vec3& direction) {
  const Vec3 u = direction.normalized();
  const double r = 1.0 + 0.15 * std::sin(5.0 * u.x() + 1.0) * std::cos(4.0 * u.y()) +
                   0.12 * std::sin(6.0 * u.z() - 0.5) + 0.1 * u.x() * u.y();
  return r * Vec3(1.2 * u.x(), 0.8 * u.y(), u.z());
}

struct Ring {
  std::vector<PointCloud> scans;  // each in its own frame
  std::vector<Matrix4> truth;     // scan i into the world
};

// `views` scans around the y axis, each of the part of the surface facing its camera, in the
// camera's frame; `noise` along the radius.
Ring MakeRing(int views, double noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<Vec3> world;
  while (world.size() < 12000) {
    const Vec3 v(gauss(rng), gauss(rng), gauss(rng));
    if (v.norm() > 1e-9) world.push_back(SurfacePoint(v));
  }
  Ring ring;
  for (int i = 0; i < views; ++i) {
    const double yaw = 2 * kPi * i / views;
    const Vec3 facing(std::sin(yaw), 0.2, std::cos(yaw));
    ring.truth.push_back(Pose(yaw, Vec3(0.3 * std::cos(yaw), 0.05 * i, 0.2)));
    const Matrix4 to_scan = ring.truth.back().inverse();
    PointCloud scan;
    for (const Vec3& p : world) {
      if (p.normalized().dot(facing.normalized()) < 0.25) continue;
      const Vec3 noisy = p + noise * gauss(rng) * p.normalized();
      scan.points.push_back(to_scan.topLeftCorner<3, 3>() * noisy + to_scan.topRightCorner<3, 1>());
    }
    ring.scans.push_back(std::move(scan));
  }
  return ring;
}

// The truth perturbed: up to `angle_deg` about a random axis and `shift` in a random direction.
std::vector<Matrix4> PerturbedPoses(const std::vector<Matrix4>& truth, double angle_deg,
                                    double shift, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<Matrix4> out;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const Vec3 axis(gauss(rng), gauss(rng), gauss(rng));
    const Vec3 dir = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
    out.push_back(i == 0 ? truth[0] : Pose(angle_deg * kPi / 180.0, shift * dir, axis) * truth[i]);
  }
  return out;
}

TEST(AlignScansTest, ARingOfViewsIsRecoveredFromPerturbedPoses) {
  const Ring ring = MakeRing(8, 0.0, 3);
  AlignOptions options;
  options.initial_poses = PerturbedPoses(ring.truth, 5.0, 0.05, 11);
  options.threads = 2;
  std::atomic<int> reported{0};
  AlignCallbacks callbacks;
  callbacks.on_edge = [&](const AlignEdge& edge, int done, int total) {
    EXPECT_EQ(total, 8);
    EXPECT_EQ(done, reported + 1);
    EXPECT_GT(edge.overlap, 0.5) << edge.from << "-" << edge.to;
    ++reported;
  };
  auto result = AlignScans(ring.scans, options, callbacks);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(reported, 8);
  ASSERT_EQ(result->poses.size(), 8u);
  ASSERT_EQ(result->edges.size(), 8u);  // loop: 7 sequential + (7, 0)
  EXPECT_EQ(result->edges.back().from, 7);
  EXPECT_EQ(result->edges.back().to, 0);
  const double d = result->sampling_distance;
  for (int i = 0; i < 8; ++i) {
    const Matrix4 expected = ring.truth[0].inverse() * ring.truth[i];  // in scan 0's frame
    EXPECT_LT(RotationErrorDeg(result->poses[i], expected), 0.1) << i;
    EXPECT_LT(TranslationError(result->poses[i], expected), 0.3 * d) << i;
  }
  for (const AlignEdge& e : result->edges) {
    EXPECT_TRUE(e.kept);
    EXPECT_GT(e.correspondences, 100);
    EXPECT_LT(e.residual_after_d, 0.5);
  }
  EXPECT_LT(result->loop_closure_error_d, 1.0);
  EXPECT_EQ(result->chain_deviation_d[0], 0.0);
  const PointCloud merged = MergeScans(ring.scans, result->poses);
  std::size_t total = 0;
  for (const PointCloud& s : ring.scans) total += s.size();
  EXPECT_EQ(merged.size(), total);
}

// A scan of something else joins the ring by an edge that cannot verify: its pose rests on no
// verified edge, and the result names it.
TEST(AlignScansTest, AScanJoinedByNoVerifiedEdgeIsNamed) {
  Ring ring = MakeRing(4, 0.0, 3);
  PointCloud other;  // a plane patch the size of a view, where scan 3 was
  for (const Vec3& p : ring.scans[3].points) other.points.emplace_back(p.x(), p.y(), 0.0);
  ring.scans[3] = other;
  AlignOptions options;
  options.pairs = PairPolicy::kSequential;
  options.initial_poses = ring.truth;
  options.threads = 2;
  auto result = AlignScans(ring.scans, options);
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_EQ(result->edges.size(), 3u);
  for (int k = 0; k < 2; ++k) {
    const VerificationScore& v = result->edges[k].verification;
    EXPECT_TRUE(result->edges[k].trusted)
        << k << ": " << VerdictName(v.verdict) << ", pull " << v.pull_fraction << ", settles by "
        << v.settle_displacement << " with a band of " << v.inlier_distance << ", RMSE " << v.rmse_d
        << " d";
  }
  EXPECT_FALSE(result->edges[2].trusted);  // (2, 3)
  EXPECT_FALSE(result->edges[2].verification.verified());
  EXPECT_EQ(result->unverified_scans, std::vector<int>{3});
}

TEST(AlignScansTest, OverlapPairsAreThoseThatOverlapUnderTheInitialPoses) {
  const Ring ring = MakeRing(6, 0.0, 5);
  AlignOptions options;
  options.initial_poses = ring.truth;
  options.pairs = PairPolicy::kOverlap;
  options.min_overlap = 0.3;
  options.overlap_distance = {3.0, false};  // exact poses: a tight band
  auto result = AlignScans(ring.scans, options);
  ASSERT_TRUE(result.ok()) << result.status();
  // Neighbours (60 degrees apart) overlap, opposite views (180 degrees) do not.
  bool has_neighbour = false, has_opposite = false;
  for (const AlignEdge& e : result->edges) {
    has_neighbour |= (e.to - e.from == 1);
    has_opposite |= (e.to - e.from == 3);
  }
  EXPECT_TRUE(has_neighbour);
  EXPECT_FALSE(has_opposite);

  // The same band in the clouds' units chooses the same pairs.
  AlignOptions absolute = options;
  absolute.overlap_distance = {3.0 * result->sampling_distance, true};
  auto same = AlignScans(ring.scans, absolute);
  ASSERT_TRUE(same.ok()) << same.status();
  ASSERT_EQ(same->edges.size(), result->edges.size());
  for (std::size_t e = 0; e < same->edges.size(); ++e) {
    EXPECT_EQ(same->edges[e].from, result->edges[e].from);
    EXPECT_EQ(same->edges[e].to, result->edges[e].to);
  }
  absolute.overlap_distance = {-1.0, true};
  EXPECT_EQ(AlignScans(ring.scans, absolute).status().message(),
            "overlap_distance: must be a positive length");
}

TEST(AlignScansTest, AStopEndsTheJobAsCancelled) {
  const Ring ring = MakeRing(6, 0.0, 7);
  AlignOptions options;
  options.initial_poses = ring.truth;
  std::atomic<bool> stop{false};
  AlignCallbacks callbacks;
  callbacks.on_edge = [&](const AlignEdge&, int, int) { stop = true; };
  callbacks.should_stop = [&] { return stop.load(); };
  auto result = AlignScans(ring.scans, options, callbacks);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kCancelled) << result.status();
}

TEST(AlignScansTest, BadInputIsRefusedNamingTheField) {
  const Ring ring = MakeRing(4, 0.0, 9);
  const auto status = [&](std::vector<PointCloud> scans, AlignOptions options) {
    return AlignScans(scans, options).status();
  };
  AlignOptions options;
  auto s = status({ring.scans[0]}, options);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "scans: need at least 2, got 1");

  options.initial_poses = {ring.truth[0], ring.truth[1]};
  s = status(ring.scans, options);
  EXPECT_EQ(s.message(), "initial_poses: 2 poses for 4 scans");

  options.initial_poses = ring.truth;
  options.initial_poses[2](0, 0) = 2.0;
  s = status(ring.scans, options);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("initial_poses[2]"), std::string_view::npos) << s.message();

  // Overlap pairs from poses that put scan 3 far away: nothing joins it.
  options.initial_poses = ring.truth;
  options.initial_poses[3] = Pose(0.0, Vec3(100, 0, 0)) * ring.truth[3];
  options.pairs = PairPolicy::kOverlap;
  s = status(ring.scans, options);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("does not join every scan: 3 not reached from scan 0"),
            std::string_view::npos)
      << s.message();

  options = AlignOptions{};
  options.anchor = 4;
  EXPECT_NE(status(ring.scans, options).message().find("anchor"), std::string_view::npos);
  std::vector<PointCloud> tiny = ring.scans;
  tiny[1].points.resize(3);
  s = status(tiny, AlignOptions{});
  EXPECT_NE(s.message().find("scans[1]"), std::string_view::npos) << s.message();
}

// ---- the merged cloud on the joint MLS surface

// Two noisy caps of the unit sphere that overlap over a quarter of it, each in its own frame.
struct SphereScans {
  std::vector<PointCloud> scans;
  std::vector<Matrix4> poses;  // scan -> world
};
SphereScans NoisySphereCaps(double noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  SphereScans out;
  for (const Vec3& facing : {Vec3(0, 0, 1), Vec3(1, 0, 1).normalized()}) {
    const Matrix4 pose = Pose(0.3 * out.scans.size(), Vec3(0.1, -0.2, 0.05) * out.scans.size());
    const Matrix4 to_scan = pose.inverse();
    PointCloud scan;
    while (scan.size() < 8000) {
      const Vec3 u = Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
      if (u.dot(facing) < 0.2) continue;
      const Vec3 p = (1.0 + noise * gauss(rng)) * u;
      scan.points.push_back(to_scan.topLeftCorner<3, 3>() * p + to_scan.topRightCorner<3, 1>());
    }
    out.scans.push_back(std::move(scan));
    out.poses.push_back(pose);
  }
  return out;
}

double RmsOffSphere(const std::vector<Vec3>& points) {
  double sum = 0.0;
  for (const Vec3& p : points) sum += (p.norm() - 1.0) * (p.norm() - 1.0);
  return std::sqrt(sum / static_cast<double>(points.size()));
}

TEST(MergedCloudTest, ResamplingPutsOnePointPerVoxelOnTheJointSurfaceAndRemovesTheNoise) {
  const double noise = 0.01;  // about a third of the caps' sampling distance
  const SphereScans caps = NoisySphereCaps(noise, 21);
  const PointCloud merged = MergeScans(caps.scans, caps.poses);
  ASSERT_EQ(merged.size(), 16000u);
  EXPECT_NEAR(RmsOffSphere(merged.points), noise, 0.1 * noise);  // merged: the scans' noise
  auto scan0 = Target::Build(caps.scans[0]);
  ASSERT_TRUE(scan0.ok());
  const double d = (*scan0)->sampling_distance();
  SurfaceResampling options;
  // Random samples: their spacing is about twice their mean NN distance.
  options.spacing = {2.0, false};
  options.threads = 2;
  auto resampled = ResampleOnMlsSurface(merged, d, options);
  ASSERT_TRUE(resampled.ok()) << resampled.status();
  const PointCloud& cloud = resampled->cloud;
  // On the sphere to under half the noise (the MLS fit at the automatic 5 d radius averages a
  // few dozen samples), with normals along the radius (but at the caps' rims, where the fit is
  // one-sided).
  EXPECT_LT(RmsOffSphere(cloud.points), 0.5 * noise);
  ASSERT_EQ(cloud.normals.size(), cloud.size());
  double mean_alignment = 0.0;
  std::size_t tilted = 0;  // more than 18 degrees off the radius
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const double alignment = std::abs(cloud.normals[i].dot(cloud.points[i].normalized()));
    tilted += alignment < 0.95;
    mean_alignment += alignment / static_cast<double>(cloud.size());
  }
  EXPECT_GT(mean_alignment, 0.98);       // about 9 degrees on average
  EXPECT_LT(tilted, cloud.size() / 20);  // the rims are a tenth of the points
  // One point per voxel: the caps' overlap is no longer doubled.
  EXPECT_LT(cloud.size(), 0.8 * merged.size());
  EXPECT_GT(cloud.size(), 0.3 * merged.size());
  EXPECT_LT(resampled->dropped, static_cast<int>(cloud.size() / 50));
  EXPECT_GE(resampled->radius_d, 5.0);  // the automatic radius' minimum
  EXPECT_NEAR(resampled->noise_sigma_d, noise / d, 0.5 * noise / d);

  // A chosen radius is used, in d or in the clouds' units; bad options are refused naming the
  // field.
  options.radius = {7.0, false};
  auto wide = ResampleOnMlsSurface(merged, d, options);
  ASSERT_TRUE(wide.ok()) << wide.status();
  EXPECT_EQ(wide->radius_d, 7.0);
  options.radius = {7.0 * d, true};
  options.spacing = {2.0 * d, true};
  auto metric = ResampleOnMlsSurface(merged, d, options);
  ASSERT_TRUE(metric.ok()) << metric.status();
  EXPECT_DOUBLE_EQ(metric->radius_d, 7.0);
  EXPECT_EQ(metric->cloud.size(), wide->cloud.size());
  options.radius = {200.0 * d, true};
  EXPECT_NE(ResampleOnMlsSurface(merged, d, options).status().message().find("is 200 d"),
            std::string::npos);
  options.radius = {7.0, false};
  options.spacing = {0.0, false};
  EXPECT_NE(ResampleOnMlsSurface(merged, d, options).status().message().find("spacing_d"),
            std::string::npos);
  EXPECT_NE(ResampleOnMlsSurface(merged, -1.0, {}).status().message().find("d:"),
            std::string::npos);
  std::atomic<bool> stop{true};
  EXPECT_EQ(ResampleOnMlsSurface(merged, d, {}, [&] { return stop.load(); }).status().code(),
            absl::StatusCode::kCancelled);
}

}  // namespace
}  // namespace mlsreg
