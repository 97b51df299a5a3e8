// Registration from any start: the feature samples, RANSAC's global candidates, verification
// against the target's MLS surface, and method auto (early exit near the truth, recovery from a
// half-turn, "not verified" for a mismatched pair, cancellation in every stage).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "mlsreg/evaluation/evaluation.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "mlsreg/registration/finish.h"
#include "mlsreg/registration/global_candidates.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/registration/verification.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

using testing::BumpyHeight;
using testing::SampleBumpySurface;

double RotationErrorDeg(const Matrix4& a, const Matrix4& b) {
  const Eigen::Matrix3d r = a.topLeftCorner<3, 3>().transpose() * b.topLeftCorner<3, 3>();
  return std::acos(std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

PointCloud Transformed(const PointCloud& cloud, const Matrix4& m) {
  PointCloud out = cloud;
  for (Vec3& p : out.points) p = m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>();
  return out;
}

struct BunnyPair {
  PointCloud source;
  std::shared_ptr<const Target> target;
  Matrix4 truth;
};

const BunnyPair& Bunny() {  // bun000 -> bun045, the bundled scans
  static const BunnyPair pair = [] {
    const std::string dir = std::string(MLSREG_SOURCE_DIR) + "/data/bunny/";
    auto manifest = ReadManifest(dir + "pairs.csv");
    EXPECT_TRUE(manifest.ok());
    BunnyPair p;
    p.source = ReadPointCloud(dir + "bun000.ply").value();
    p.target = Target::Build(ReadPointCloud(dir + "bun045.ply").value()).value();
    p.truth = *manifest->problems[0].ground_truth;
    return p;
  }();
  return pair;
}

TEST(FeatureCloudTest, LargeCloudsGetLargerVoxelsAndAtMostTheCapOfSamples) {
  const PointCloud dense = SampleBumpySurface(60'000, -1.0, 1.0, 1, 0.0);
  const KdTree tree(dense.points);
  const double d = SamplingDistance(dense.points, tree);
  const FeatureScale scale = ChooseFeatureScale(dense.points, d);
  EXPECT_GT(scale.voxel, kFeatureVoxelD * d);  // 60k points give more than 2500 voxels at 3 d
  EXPECT_LE(VoxelRepresentatives(dense.points, scale.voxel).size(), kMaxFeatureSamples);
  EXPECT_DOUBLE_EQ(scale.feature_radius, kFeatureRadiusPerVoxel * scale.voxel);
  auto features = BuildFeatureCloud(dense.points, tree, nullptr, 5 * d, std::nullopt, scale);
  ASSERT_TRUE(features.has_value());
  EXPECT_GT(features->size(), kMaxFeatureSamples / 2);
  EXPECT_EQ(features->features.size(), features->size());
  // Normals of the height field z = f(x, y) are close to the analytic ones.
  for (std::size_t i = 0; i < features->size(); i += 97) {
    const Vec3& p = features->points[i];
    const double h = 1e-5;
    const Vec3 analytic =
        Vec3(-(BumpyHeight(p.x() + h, p.y()) - BumpyHeight(p.x() - h, p.y())) / (2 * h),
             -(BumpyHeight(p.x(), p.y() + h) - BumpyHeight(p.x(), p.y() - h)) / (2 * h), 1.0)
            .normalized();
    EXPECT_GT(std::abs(features->normals[i].dot(analytic)), 0.98) << i;
  }
}

TEST(FeatureCloudTest, TheTargetMakesItsFeaturesOnFirstUseAndCountsTheirBytes) {
  const Target& target = *Bunny().target;
  auto lazy = Target::Build(target.cloud()).value();
  const std::size_t before = lazy->MemoryBytes();
  const FeatureCloud* features = lazy->features();
  ASSERT_NE(features, nullptr);
  EXPECT_GT(features->size(), 500u);
  EXPECT_EQ(lazy->features(), features);  // made once
  EXPECT_EQ(lazy->MemoryBytes() - before, features->MemoryBytes());
  // The same features as a target that made them at build.
  auto eager = Target::Build(target.cloud(), TargetOptions::AllWithTarget()).value();
  ASSERT_EQ(eager->features()->size(), features->size());
  EXPECT_EQ(eager->features()->points, features->points);
  EXPECT_EQ(eager->features()->normals, features->normals);
  // A stop requested while they are made leaves none, and the next caller makes them.
  auto stopped = Target::Build(target.cloud()).value();
  EXPECT_EQ(stopped->features([] { return true; }), nullptr);
  ASSERT_NE(stopped->features(), nullptr);
  EXPECT_EQ(stopped->features()->points, features->points);
}

// A half-turned copy of the bunny's target scan, registered to the scan it came from: the best
// candidate is the truth to within a voxel, whatever the start.
TEST(GlobalCandidatesTest, RansacFindsAHalfTurnFromFeaturesAlone) {
  const Target& target = *Bunny().target;
  const Matrix4 truth = RandomPerturbation(170.0, 0.05, Vec3::Zero(), 3);  // source -> target
  const PointCloud source = Transformed(target.cloud(), truth.inverse());
  const KdTree tree(source.points);
  const FeatureScale scale = target.features()->scale;
  auto features = BuildFeatureCloud(source.points, tree, nullptr, 5 * target.sampling_distance(),
                                    std::nullopt, scale);
  ASSERT_TRUE(features.has_value());
  GlobalCandidateOptions options;
  options.inlier_distance = 1.5 * scale.voxel;
  const GlobalCandidates found = FindGlobalCandidates(*features, *target.features(), options);
  ASSERT_FALSE(found.candidates.empty());
  EXPECT_LE(found.candidates.size(), 8u);
  EXPECT_GT(found.matches, 100);
  const Matrix4& best = found.candidates.front().transform;
  EXPECT_LT(RotationErrorDeg(best, truth), 3.0);
  EXPECT_LT(EvaluatePose(source.points, best, truth, target.sampling_distance()).rmse_d,
            scale.voxel / target.sampling_distance());
  for (std::size_t k = 1; k < found.candidates.size(); ++k) {
    EXPECT_LE(found.candidates[k].inliers, found.candidates[k - 1].inliers);
  }
}

TEST(VerificationTest, TheTruthVerifiesAndAWrongPoseOrAnotherObjectDoesNot) {
  const BunnyPair& bunny = Bunny();
  const Target& target = *bunny.target;
  const VoxelCloud samples =
      BuildVoxelCloud(bunny.source.points, target.voxel_cloud().voxel, bunny.source.viewpoint);
  const NoiseLevels noise{0.1 * target.sampling_distance(), 0.1 * target.sampling_distance()};
  const auto verify = [&](const Matrix4& pose) {
    return VerifyAlignment(target, samples, pose, noise);
  };
  const VerificationScore right = verify(bunny.truth);
  EXPECT_TRUE(right.verified()) << VerdictName(right.verdict);
  EXPECT_GT(right.inlier_fraction, 0.6);
  EXPECT_LT(right.rmse_d, 1.0);
  EXPECT_EQ(right.samples, static_cast<int>(samples.size()));
  const Vec3 centre = bunny.truth.topLeftCorner<3, 3>() * samples.points[0];
  for (double angle : {5.0, 10.0, 20.0}) {
    const VerificationScore turned =
        verify(RandomPerturbation(angle, 0.0, centre, 5) * bunny.truth);
    EXPECT_FALSE(turned.verified()) << angle << " degrees: " << turned.inlier_fraction;
  }

  // A bumpy sheet as large as the bunny, laid through its middle, is mostly off its surface.
  PointCloud sheet = SampleBumpySurface(20'000, -1.0, 1.0, 4, 0.0);
  for (Vec3& p : sheet.points) p = 0.05 * p + target.points()[0];
  const VoxelCloud sheet_samples =
      BuildVoxelCloud(sheet.points, target.voxel_cloud().voxel, std::nullopt);
  const VerificationScore other =
      VerifyAlignment(target, sheet_samples, Matrix4::Identity(), noise);
  EXPECT_FALSE(other.verified());
  EXPECT_LT(other.inlier_fraction, 0.5);
}

// The caches one verification leaves for the next (auto keeps them from a pose to its finish)
// answer exactly as the trees do: poses near and far, in any order, and another sample set (which
// resets them), score bit for bit as without them.
TEST(VerificationTest, CachesKeptFromOtherPosesChangeNoScore) {
  const BunnyPair& bunny = Bunny();
  const Target& target = *bunny.target;
  const VoxelCloud samples =
      BuildVoxelCloud(bunny.source.points, target.voxel_cloud().voxel, bunny.source.viewpoint);
  const VoxelCloud fewer = BuildVoxelCloud(bunny.source.points, 2.0 * target.voxel_cloud().voxel,
                                           bunny.source.viewpoint);
  const NoiseLevels noise{0.1 * target.sampling_distance(), 0.1 * target.sampling_distance()};
  const Vec3 centre = bunny.truth.topLeftCorner<3, 3>() * samples.points[0];
  const double d = target.sampling_distance();
  const std::vector<Matrix4> poses = {
      RandomPerturbation(0.3, 0.5 * d, centre, 1) * bunny.truth,
      bunny.truth,
      RandomPerturbation(20.0, 0.0, centre, 2) * bunny.truth,
      RandomPerturbation(0.1, 0.2 * d, centre, 3) * bunny.truth,
  };
  VerificationCaches caches;
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t k = 0; k < poses.size(); ++k) {
      const VoxelCloud& cloud = (pass == 1 && k == 2) ? fewer : samples;
      const VerificationScore plain = VerifyAlignment(target, cloud, poses[k], noise);
      const VerificationScore kept =
          VerifyAlignment(target, cloud, poses[k], noise, {}, 1, &caches);
      SCOPED_TRACE(::testing::Message() << "pass " << pass << ", pose " << k);
      EXPECT_EQ(kept.verdict, plain.verdict);
      EXPECT_EQ(kept.covered, plain.covered);
      EXPECT_EQ(kept.inliers, plain.inliers);
      EXPECT_EQ(kept.rmse_d, plain.rmse_d);
      EXPECT_EQ(kept.settle_displacement, plain.settle_displacement);
      EXPECT_EQ(kept.coherent_residual, plain.coherent_residual);
      EXPECT_EQ(kept.worst_direction_error, plain.worst_direction_error);
      EXPECT_EQ(caches.samples.size(), cloud.size());
    }
  }
  EXPECT_TRUE(VerifyAlignment(target, samples, bunny.truth, noise, {}, 1, &caches).verified());
}

// Another shape laid on the target within its band: a noisy bumpy sheet against the same sheet
// with a smooth ripple of about one noise sigma of the band (RMS) added. Most samples agree, the
// residuals stay concentrated and nothing pulls; but neighbouring samples share the ripple,
// which noise never does.
TEST(VerificationTest, AnotherShapeWithinTheBandShowsInResidualsThatNeighboursShare) {
  const double noise = 0.01;
  auto target = Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, noise)).value();
  const auto sheet = [&](double ripple) {
    PointCloud cloud = SampleBumpySurface(20'000, -1.0, 1.0, 2, noise);
    for (Vec3& p : cloud.points) p.z() += ripple * std::sin(8.0 * p.x()) * std::sin(8.0 * p.y());
    return cloud;
  };
  const VerificationScore same = VerifyPose(*target, sheet(0.0), Matrix4::Identity());
  EXPECT_TRUE(same.verified()) << VerdictName(same.verdict);
  const double sigma = same.inlier_distance / VerificationOptions().band_per_noise;
  EXPECT_LT(same.coherent_residual, 0.5 * sigma);
  // A ripple of amplitude a has an RMS of a / 2: 3 sigma gives 1.5 noise sigmas of one cloud,
  // about one of the band's (both clouds' noise); neighbours two voxels apart share most of it
  // (at 2.8 sigma they shared 0.899 band sigmas against the verdict's limit of 0.9: too close).
  const VerificationScore other = VerifyPose(*target, sheet(3.0 * noise), Matrix4::Identity());
  EXPECT_EQ(other.verdict, Verdict::kCoherentResiduals)
      << VerdictName(other.verdict) << " inliers " << other.inlier_fraction << " coherent "
      << other.coherent_residual / sigma << " sigma";
  EXPECT_GT(other.inlier_fraction, 0.9);
  EXPECT_GT(other.coherent_residual, VerificationOptions().max_coherent_sigmas * sigma);
}

// A street: a flat road between two walls, with posts along one side. Slid along the road the
// road and the walls still agree; only the posts say no, and the verdict must listen to them.
PointCloud Street(bool with_posts, double noise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  PointCloud street;
  const double step = 0.1;
  for (double x = -20.0; x <= 20.0; x += step) {
    for (double y = -6.0; y <= 6.0; y += step) street.points.emplace_back(x, y, gauss(rng));
    for (double z = 0.0; z <= 5.0; z += step) {
      street.points.emplace_back(x, -6.0 + gauss(rng), z);
      street.points.emplace_back(x, 6.0 + gauss(rng), z);
    }
  }
  if (with_posts) {
    for (double px = -18.0; px <= 18.0; px += 4.0) {  // square posts 0.4 m wide, 3 m tall
      for (double z = 0.0; z <= 3.0; z += step) {
        for (double t = -0.2; t <= 0.2; t += step / 2) {
          street.points.emplace_back(px + t, 4.0 - 0.2 + gauss(rng), z);
          street.points.emplace_back(px + t, 4.0 + 0.2 + gauss(rng), z);
          street.points.emplace_back(px - 0.2 + gauss(rng), 4.0 + t, z);
          street.points.emplace_back(px + 0.2 + gauss(rng), 4.0 + t, z);
        }
      }
    }
  }
  return street;
}

TEST(VerificationTest, APoseSlidAlongTheRoadDoesNotVerify) {
  const double noise = 0.01;
  auto target = Target::Build(Street(true, noise, 1)).value();
  const PointCloud source = Street(true, noise, 2);
  Matrix4 slid = Matrix4::Identity();
  slid(0, 3) = 1.0;  // a metre along the road: half way between two posts' faces
  const VerificationScore right = VerifyPose(*target, source, Matrix4::Identity());
  EXPECT_TRUE(right.verified()) << VerdictName(right.verdict) << " " << right.inlier_fraction;
  const VerificationScore wrong = VerifyPose(*target, source, slid);
  EXPECT_FALSE(wrong.verified()) << wrong.inlier_fraction;
  // The posts' samples, a metre off their posts, either disagree or leave the overlap; either
  // way nothing left confirms the position along the road.
  EXPECT_TRUE(wrong.verdict == Verdict::kDirectionDisagrees ||
              wrong.verdict == Verdict::kUnconstrained)
      << VerdictName(wrong.verdict);
  EXPECT_GT(std::abs(wrong.worst_direction[3]), 0.9);  // translation along x
  EXPECT_GT(wrong.inlier_fraction, 0.7);               // most of the street still agrees
}

TEST(VerificationTest, ARoadWithoutCrossStructureCannotBeVerified) {
  auto target = Target::Build(Street(false, 0.01, 1)).value();
  const VerificationScore score = VerifyPose(*target, Street(false, 0.01, 2), Matrix4::Identity());
  EXPECT_EQ(score.verdict, Verdict::kUnconstrained);
  EXPECT_GT(std::abs(score.worst_direction[3]), 0.9);  // nothing says where along x
  EXPECT_GT(score.inlier_fraction, 0.9);
}

// A corner of a clean machined part: a floor and a wall, and one small face across them that
// alone fixes the position along x. Two samplings of it, at the true pose.
PointCloud MachinedCorner(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.004, 0.004);
  PointCloud part;
  const double step = 0.02;
  for (double a = 0.0; a <= 2.0; a += step) {
    for (double b = 0.0; b <= 2.0; b += step) {
      part.points.emplace_back(a + jitter(rng), b + jitter(rng), 0.0);                // floor z = 0
      if (b <= 1.0) part.points.emplace_back(a + jitter(rng), 0.0, b + jitter(rng));  // wall
    }
  }
  for (double b = 0.0; b <= 0.1; b += step) {  // a small face x = 1, facing -x
    for (double c = 0.0; c <= 0.1; c += step) {
      part.points.emplace_back(1.0, 0.4 + b + jitter(rng), c + jitter(rng));
    }
  }
  return part;
}

// Near a sharp edge a sample's normal is fitted across the edge, tens of degrees from the face
// the target finds there, so its product of normals is arbitrary. Such samples (here one floor
// sample in six with its normal tilted 85 degrees toward +-x) take no part in the directional
// test: the verdict and the weakest direction's error are those of the clean samples. Counted,
// they feign information along x (the error falls by a factor of three) or drown the small
// face's (a smaller face, or more of them).
TEST(VerificationTest, NormalsThatDisagreeWithTheTargetsBeyondNoiseTakeNoPartInTheDirections) {
  auto target = Target::Build(MachinedCorner(1)).value();
  const VoxelCloud clean =
      BuildVoxelCloud(MachinedCorner(2).points, target->voxel_cloud().voxel, std::nullopt);
  VoxelCloud edgy =
      BuildVoxelCloud(MachinedCorner(2).points, target->voxel_cloud().voxel, std::nullopt);
  const double tilt = 85.0 * std::numbers::pi / 180.0;
  int tilted = 0;
  for (std::size_t i = 0; i < edgy.size(); ++i) {
    if (edgy.points[i].z() > 0.01 || i % 6 != 0) continue;
    edgy.normals[i] = Vec3((i % 12 ? 1.0 : -1.0) * std::sin(tilt), 0.0, std::cos(tilt));
    ++tilted;
  }
  ASSERT_GT(tilted, 300);
  const NoiseLevels noiseless{0.0, 0.0};
  const VerificationScore expected =
      VerifyAlignment(*target, clean, Matrix4::Identity(), noiseless);
  const VerificationScore score = VerifyAlignment(*target, edgy, Matrix4::Identity(), noiseless);
  EXPECT_TRUE(expected.verified()) << VerdictName(expected.verdict);
  EXPECT_EQ(score.verdict, expected.verdict) << VerdictName(score.verdict);
  EXPECT_GT(std::abs(score.worst_direction[3]), 0.9);  // translation along x: the small face
  // The same to the few tilted samples that had been on an edge already or outside the overlap
  // (the counterfactual, counting them: 1.0e-4, a third).
  EXPECT_NEAR(score.worst_direction_error, expected.worst_direction_error,
              0.01 * expected.worst_direction_error);
  EXPECT_LE(score.edge_samples, expected.edge_samples + tilted);
  EXPECT_GE(score.edge_samples, expected.edge_samples + tilted - tilted / 100);
  EXPECT_LT(score.normal_angle_median_deg, 5.0);

  // Slid along x by more than the band, the small face leaves it: not verified.
  Matrix4 slid = Matrix4::Identity();
  slid(0, 3) = 0.05;
  EXPECT_FALSE(VerifyAlignment(*target, edgy, slid, noiseless).verified());
}

// Points above a sampled plane are their height away from its MLS surface; far from the samples
// the distance is the one to the nearest sample.
// A longer settling than the verification's own (auto's finish) that moves a verified pose
// beyond the verdict's settling bound makes it pulled, with that settling; within the bound, or
// for a pose that was not verified, nothing changes.
TEST(VerificationTest, ASettlingBeyondTheBoundPullsAVerifiedPose) {
  auto target = Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, 0.01)).value();
  const PointCloud source = SampleBumpySurface(20'000, -1.0, 1.0, 2, 0.01);
  const VerificationScore right = VerifyPose(*target, source, Matrix4::Identity());
  ASSERT_TRUE(right.verified()) << VerdictName(right.verdict);
  const VerificationOptions options;
  const double median_spacing = target->scales().median_spacing;
  // The bound: one noise sigma of the band (band / 3), at least one median spacing.
  const double bound = std::max(right.inlier_distance / options.band_per_noise,
                                options.min_band_spacings * median_spacing);

  VerificationScore within = right;
  EXPECT_FALSE(PulledBySettling(within, 0.9 * bound, median_spacing));
  EXPECT_EQ(within.verdict, Verdict::kVerified);
  EXPECT_EQ(within.settle_displacement, right.settle_displacement);

  VerificationScore beyond = right;
  EXPECT_TRUE(PulledBySettling(beyond, 1.1 * bound, median_spacing));
  EXPECT_EQ(beyond.verdict, Verdict::kPulled);
  EXPECT_FALSE(beyond.verified());
  EXPECT_EQ(beyond.settle_displacement, 1.1 * bound);
  EXPECT_EQ(beyond.inliers, right.inliers);

  // Only a verified pose is judged again.
  Matrix4 lifted = Matrix4::Identity();
  lifted(2, 3) = 0.3;
  VerificationScore wrong = VerifyPose(*target, source, lifted);
  ASSERT_FALSE(wrong.verified());
  const Verdict before = wrong.verdict;
  EXPECT_FALSE(PulledBySettling(wrong, 100.0 * bound, median_spacing));
  EXPECT_EQ(wrong.verdict, before);
}

// The probes of the rival search: a motion along the weakest direction by a distance moves the
// samples by about that much; a translation exactly, a rotation about the samples' centre at
// their RMS radius (the lever).
TEST(VerificationTest, AMotionAlongTheWorstDirectionMovesTheSamplesByTheDistance) {
  VerificationScore score;
  score.worst_direction << 0, 0, 0, 3, 0, 0;  // any length: along x
  const Matrix4 start = RandomPerturbation(20.0, 1.0, Vec3::Zero(), 7);
  const Matrix4 slid = MovedAlongWorstDirection(score, start, 0.5);
  EXPECT_LT(RotationErrorDeg(slid, start), 1e-9);
  EXPECT_LT(((slid.col(3) - start.col(3)).head<3>() - Vec3(0.5, 0.0, 0.0)).norm(), 1e-12);

  score.worst_direction << 0, 0, 1, 0, 0, 0;  // a turn about z
  score.direction_centre = Vec3(1.0, 1.0, 0.0);
  score.direction_lever = 2.0;
  const Matrix4 turned = MovedAlongWorstDirection(score, Matrix4::Identity(), 0.2);
  const auto moved = [&](const Vec3& p) {
    return turned.topLeftCorner<3, 3>() * p + turned.topRightCorner<3, 1>();
  };
  EXPECT_LT((moved(score.direction_centre) - score.direction_centre).norm(), 1e-12);
  const Vec3 at_lever = score.direction_centre + Vec3(2.0, 0.0, 0.0);
  EXPECT_NEAR((moved(at_lever) - at_lever).norm(), 0.2, 1e-3);  // 0.1 rad at 2: a chord of 0.19992
  EXPECT_NEAR(RotationErrorDeg(turned, Matrix4::Identity()), 0.1 * 180.0 / std::numbers::pi, 1e-9);
}

TEST(VerificationTest, DistancesToTheMlsSurfaceOfAPlane) {
  auto plane = Target::Build(testing::SamplePlaneGrid(1.0, 0.02, 0.002, 3)).value();
  const std::vector<Vec3> points = {Vec3(0.1, 0.2, 0.0), Vec3(0.1, 0.2, 0.03),
                                    Vec3(-0.3, 0.4, -0.05), Vec3(3.0, 0.0, 0.0)};
  const std::vector<double> distances = DistancesToMlsSurface(*plane, points);
  ASSERT_EQ(distances.size(), 4u);
  EXPECT_NEAR(distances[0], 0.0, 1e-3);
  EXPECT_NEAR(distances[1], 0.03, 1e-3);
  EXPECT_NEAR(distances[2], 0.05, 1e-3);
  EXPECT_NEAR(distances[3], 2.0, 0.03);  // to the nearest corner sample, about (1, 0, 0)
}

// Near the truth there is no global stage. The bunny's scans are clean (plane-to-plane finish),
// so the verified voxel alignment goes straight to the finish; without a finish, MLS-SICP
// refines it.
TEST(AutoMethodTest, NearTheTruthItAlignsTheVoxelCloudsThenFinishesWithoutAGlobalStage) {
  const BunnyPair& bunny = Bunny();
  const Matrix4 start =
      PerturbedStart(bunny.source, bunny.truth, bunny.target->sampling_distance(), {10.0, 10.0, 1});
  for (const bool finish : {true, false}) {
    SCOPED_TRACE(finish);
    RegistrationOptions options;
    ASSERT_EQ(options.method, Method::kAuto);  // the default
    options.automatic.finish = finish;
    std::vector<Stage> stages;
    RegistrationCallbacks callbacks;
    callbacks.on_iteration = [&](const IterationReport& r) {
      if (stages.empty() || stages.back() != r.stage) stages.push_back(r.stage);
    };
    auto automatic = Register(*bunny.target, bunny.source, start, options, callbacks);
    ASSERT_TRUE(automatic.ok()) << automatic.status();
    ASSERT_TRUE(automatic->auto_report.has_value());
    const AutoReport& report = *automatic->auto_report;
    EXPECT_TRUE(report.early_exit);
    EXPECT_TRUE(report.verified);
    ASSERT_TRUE(automatic->verification.has_value());
    EXPECT_TRUE(automatic->verification->verified());
    EXPECT_EQ(report.candidates.size(), 1u);
    EXPECT_EQ(report.chosen, 0);
    EXPECT_EQ(report.timings.global, 0.0);
    if (finish) {
      ASSERT_EQ(report.finish.kind, FinishKind::kPlaneToPlane);
      EXPECT_TRUE(report.finish.kept);
      EXPECT_EQ(stages, (std::vector<Stage>{Stage::kCoarse, Stage::kFinish}));
    } else {
      EXPECT_EQ(stages, (std::vector<Stage>{Stage::kCoarse, Stage::kStart}));
    }
    const PoseError error = EvaluatePose(bunny.source.points, automatic->transform, bunny.truth,
                                         automatic->sampling_distance);
    EXPECT_LT(error.rmse_d, finish ? 0.3 : 1.0);
  }
}

// The finish polishes what it can bring to the data's optimum: a verified result, and a pulled
// one (right, but a small step short of it); never a pose the data reject otherwise.
TEST(AutoMethodTest, TheFinishPolishesVerifiedAndPulledResultsOnly) {
  for (const Verdict verdict :
       {Verdict::kVerified, Verdict::kTooLittleOverlap, Verdict::kLowAgreement,
        Verdict::kDiffuseResiduals, Verdict::kDirectionDisagrees, Verdict::kUnconstrained,
        Verdict::kPulled, Verdict::kCoherentResiduals, Verdict::kAmbiguous, Verdict::kSeenThrough,
        Verdict::kSeenFromBehind}) {
    SCOPED_TRACE(std::string(VerdictName(verdict)));
    EXPECT_EQ(FinishPolishes(verdict),
              verdict == Verdict::kVerified || verdict == Verdict::kPulled);
  }
}

// A verified start that covers less of the source than accept_fraction asks for is confirmed by
// the global stage: the start competes with the candidates and stays when none explains more.
TEST(AutoMethodTest, AStartCoveringTooLittleIsConfirmedGlobally) {
  const BunnyPair& bunny = Bunny();
  const Matrix4 start =
      PerturbedStart(bunny.source, bunny.truth, bunny.target->sampling_distance(), {10.0, 10.0, 1});
  RegistrationOptions options;
  options.automatic.accept_fraction = 0.95;  // the scans overlap by about 87 %
  auto result = Register(*bunny.target, bunny.source, start, options);
  ASSERT_TRUE(result.ok()) << result.status();
  const AutoReport& report = *result->auto_report;
  EXPECT_TRUE(report.candidates[0].score.verified());
  EXPECT_LT(report.candidates[0].score.covered_fraction(), options.automatic.accept_fraction);
  EXPECT_EQ(report.chosen, 0);  // no candidate explains more by 1 %
  EXPECT_FALSE(report.early_exit);
  EXPECT_TRUE(report.verified);
  // Candidates whose alignment reached the start's pose stop there (within the final capture
  // range of two working voxels) and are not verified again: they carry the start's score.
  int in_basin = 0, stopped_early = 0;
  for (std::size_t k = 1; k < report.candidates.size(); ++k) {
    const AutoCandidate& c = report.candidates[k];
    if (!c.in_start_basin) continue;
    ++in_basin;
    stopped_early += c.iterations < options.automatic.candidate_iterations;
    EXPECT_EQ(c.score.inliers, report.candidates[0].score.inliers);
    EXPECT_LE(RmsDistanceBetween(bunny.source.points, c.refined, report.candidates[0].refined),
              2.0 * bunny.target->voxel_cloud().voxel);
  }
  EXPECT_GT(in_basin, 0);
  EXPECT_GT(stopped_early, 0);
  EXPECT_LT(
      EvaluatePose(bunny.source.points, result->transform, bunny.truth, result->sampling_distance)
          .rmse_d,
      1.0);
}

TEST(AutoMethodTest, FromAHalfTurnItFindsTheTruthAndSaysWhichCandidateWon) {
  const BunnyPair& bunny = Bunny();
  const Matrix4 start = PerturbedStart(bunny.source, bunny.truth, bunny.target->sampling_distance(),
                                       {180.0, 30.0, 2});
  std::vector<Stage> stages;
  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [&](const IterationReport& r) {
    if (stages.empty() || stages.back() != r.stage) stages.push_back(r.stage);
  };
  auto result = Register(*bunny.target, bunny.source, start, {}, callbacks);
  ASSERT_TRUE(result.ok()) << result.status();
  const PoseError error =
      EvaluatePose(bunny.source.points, result->transform, bunny.truth, result->sampling_distance);
  EXPECT_LT(error.rmse_d, 1.0);
  EXPECT_LT(error.rotation_deg, 0.5);
  const AutoReport& report = *result->auto_report;
  EXPECT_FALSE(report.early_exit);
  EXPECT_TRUE(report.verified);
  ASSERT_GE(report.candidates.size(), 2u);
  EXPECT_EQ(report.candidates[0].origin, CandidateOrigin::kStart);
  EXPECT_FALSE(report.candidates[0].score.verified());  // local alignment alone fails here
  ASSERT_GT(report.chosen, 0);
  EXPECT_EQ(report.candidates[report.chosen].origin, CandidateOrigin::kGlobal);
  for (const AutoCandidate& c : report.candidates) {
    EXPECT_FALSE(c.in_start_basin);  // the start did not verify: every candidate is its own
  }
  // The first candidate that verifies over at least accept_fraction of the source ends the
  // search, as the start would have: it is the last one tried, and the one chosen.
  const RegistrationOptions defaults;
  const auto acceptable = [&](const AutoCandidate& c) {
    return c.score.verified() && c.score.covered_fraction() >= defaults.automatic.accept_fraction;
  };
  ASSERT_TRUE(acceptable(report.candidates.back()));
  for (std::size_t k = 1; k + 1 < report.candidates.size(); ++k) {
    EXPECT_FALSE(acceptable(report.candidates[k])) << k;
  }
  EXPECT_EQ(report.chosen, static_cast<int>(report.candidates.size()) - 1);
  EXPECT_TRUE(report.verification.verified());
  EXPECT_GT(report.verification.inlier_fraction, 0.6);
  EXPECT_GT(report.feature_matches, 50);
  EXPECT_GT(report.timings.global, 0.0);
  EXPECT_GT(report.timings.final, 0.0);
  // The stream shows the stages in order.
  ASSERT_GE(stages.size(), 5u);
  EXPECT_EQ(stages[0], Stage::kCoarse);
  EXPECT_EQ(stages[1], Stage::kStart);
  EXPECT_EQ(stages[2], Stage::kGlobal);
  EXPECT_EQ(stages[3], Stage::kCandidate);
  // The chosen candidate's voxel alignment verified, and the clean scans take the plane-to-plane
  // finish: no MLS-SICP refinement between them.
  ASSERT_TRUE(report.finish.kept);
  ASSERT_EQ(report.finish.kind, FinishKind::kPlaneToPlane);
  EXPECT_TRUE(report.candidates[report.chosen].score.verified());
  EXPECT_EQ(stages[stages.size() - 2], Stage::kCandidate);
  EXPECT_EQ(stages.back(), Stage::kFinish);
  EXPECT_EQ(result->trace.back().stage, Stage::kFinish);
  EXPECT_EQ(result->trace.back().candidate, report.chosen);
}

TEST(AutoMethodTest, AnotherObjectIsNotVerified) {
  const BunnyPair& bunny = Bunny();
  PointCloud sheet = SampleBumpySurface(20'000, -1.0, 1.0, 6, 0.0);
  for (Vec3& p : sheet.points) p = 0.05 * p + bunny.target->points()[0];
  auto result = Register(*bunny.target, sheet, Matrix4::Identity(), {});
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_TRUE(result->auto_report.has_value());
  EXPECT_FALSE(result->auto_report->verified);
  ASSERT_TRUE(result->verification.has_value());
  EXPECT_FALSE(result->verification->verified());
  EXPECT_GT(result->auto_report->candidates.size(), 1u);  // it did look globally
  // Last, with nothing verified, MLS-SICP alone from the caller's start (no voxel stage): it
  // does not verify either, so the start's own result is returned.
  const AutoCandidate& direct = result->auto_report->candidates.back();
  EXPECT_EQ(direct.origin, CandidateOrigin::kDirect);
  EXPECT_TRUE(direct.start.isApprox(Matrix4::Identity()));
  EXPECT_GT(direct.iterations, 0);
  EXPECT_FALSE(direct.score.verified());
  EXPECT_EQ(result->auto_report->chosen, 0);
}

// A corridor from x = -`half_length` to `half_length`: a floor between two walls 4 m apart, and
// pillars against one wall at `pillars` (x). Only the pillars' faces fix the position along it.
PointCloud Corridor(const std::vector<double>& pillars, double half_length, double noise,
                    std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  PointCloud corridor;
  const double step = 0.1;
  for (double x = -half_length; x <= half_length; x += step) {
    for (double y = -2.0; y <= 2.0; y += step) corridor.points.emplace_back(x, y, gauss(rng));
    for (double z = 0.0; z <= 3.0; z += step) {
      corridor.points.emplace_back(x, -2.0 + gauss(rng), z);
      corridor.points.emplace_back(x, 2.0 + gauss(rng), z);
    }
  }
  for (const double px : pillars) {  // 0.6 m wide, 0.3 m deep, 1.5 m tall
    if (std::abs(px) > half_length) continue;
    for (double z = 0.0; z <= 1.5; z += step) {
      for (double t = 0.0; t <= 0.3; t += step / 2) {
        corridor.points.emplace_back(px - 0.3 + gauss(rng), 1.7 + t, z);
        corridor.points.emplace_back(px + 0.3 + gauss(rng), 1.7 + t, z);
      }
      for (double t = -0.3; t <= 0.3; t += step / 2) {
        corridor.points.emplace_back(px + t, 1.7 + gauss(rng), z);
      }
    }
  }
  return corridor;
}

// Pillars every 2 m, and a scan of the corridor's middle 30 m: the pose slid by one period
// explains the scan as well as the truth does. From the truth, the result verifies on its own,
// but the rival search finds the other pose and the result is ambiguous, not verified.
TEST(AutoMethodTest, APoseAmongRepeatedPillarsHasARivalAndIsAmbiguous) {
  std::vector<double> pillars;
  for (double x = -18.0; x <= 18.0; x += 2.0) pillars.push_back(x);
  auto target = Target::Build(Corridor(pillars, 20.0, 0.01, 1)).value();
  const PointCloud source = Corridor(pillars, 15.0, 0.01, 2);
  auto result = Register(*target, source, Matrix4::Identity(), {});
  ASSERT_TRUE(result.ok()) << result.status();
  const AutoReport& report = result->auto_report.value();
  EXPECT_LT(result->transform.col(3).head<3>().norm(), 0.05);  // the truth, kept
  EXPECT_EQ(report.verification.verdict, Verdict::kAmbiguous);
  EXPECT_FALSE(report.verified);
  ASSERT_TRUE(report.rival.has_value());
  const AutoCandidate& rival = report.candidates.at(*report.rival);
  EXPECT_EQ(rival.origin, CandidateOrigin::kRival);
  // One period along the corridor, either way, explaining about as much.
  EXPECT_NEAR(std::abs(rival.refined(0, 3)), 2.0, 0.2) << rival.refined;
  EXPECT_GT(rival.score.inliers, 0.95 * report.verification.inliers);
  EXPECT_GT(report.timings.rivals, 0.0);
  ASSERT_TRUE(result->rival.has_value());  // the result names it too, as for any method
  EXPECT_EQ(result->rival->refined, rival.refined);
  EXPECT_EQ(result->verification->verdict, Verdict::kAmbiguous);
}

// The verdict names the translation its agreeing samples fix least: along a corridor, where only
// the pillars' faces fix it (the rival search probes it where the worst direction is a rotation).
TEST(VerificationTest, TheWeakestTranslationRunsAlongACorridor) {
  std::vector<double> pillars;
  for (double x = -18.0; x <= 18.0; x += 2.0) pillars.push_back(x);
  auto target = Target::Build(Corridor(pillars, 20.0, 0.01, 1)).value();
  const VerificationScore score =
      VerifyPose(*target, Corridor(pillars, 15.0, 0.01, 2), Matrix4::Identity());
  EXPECT_NEAR(score.weakest_translation.norm(), 1.0, 1e-9);
  EXPECT_GT(std::abs(score.weakest_translation.x()), 0.95) << score.weakest_translation;
  EXPECT_GT(score.weakest_translation_strength, 0.0);
  EXPECT_LT(score.weakest_translation_strength, 0.02);
}

// Every method's verdict searches for a rival as auto's does: MLS-SICP and G-ICP from the truth
// among repeated pillars end there, verify on their own, and are ambiguous; the probes stream
// as stage `rival`.
TEST(VerificationTest, AnyMethodsPoseAmongRepeatedPillarsIsAmbiguous) {
  std::vector<double> pillars;
  for (double x = -18.0; x <= 18.0; x += 2.0) pillars.push_back(x);
  auto target = Target::Build(Corridor(pillars, 20.0, 0.01, 1)).value();
  const PointCloud source = Corridor(pillars, 15.0, 0.01, 2);
  for (const Method method : {Method::kMlsSicp, Method::kGicp}) {
    SCOPED_TRACE(std::string(MethodName(method)));
    RegistrationOptions options;
    options.method = method;
    int rival_reports = 0;
    RegistrationCallbacks callbacks;
    callbacks.on_iteration = [&](const IterationReport& r) {
      rival_reports += r.stage == Stage::kRival;
    };
    auto result = Register(*target, source, Matrix4::Identity(), options, callbacks);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_LT(result->transform.col(3).head<3>().norm(), 0.05);
    ASSERT_TRUE(result->verification.has_value());
    EXPECT_EQ(result->verification->verdict, Verdict::kAmbiguous);
    ASSERT_TRUE(result->rival.has_value());
    EXPECT_EQ(result->rival->origin, CandidateOrigin::kRival);
    EXPECT_NEAR(std::abs(result->rival->refined(0, 3)), 2.0, 0.2) << result->rival->refined;
    EXPECT_GT(rival_reports, 0);
  }
  // A pose given by the caller (mlsreg verify) gets the same verdict; VerifyPose alone, without
  // the search, verifies it.
  const PoseVerdict given = VerifyPoseSearchingRivals(*target, source, Matrix4::Identity());
  EXPECT_EQ(given.score.verdict, Verdict::kAmbiguous);
  ASSERT_TRUE(given.rival.has_value());
  EXPECT_NEAR(std::abs(given.rival->refined(0, 3)), 2.0, 0.2);
  EXPECT_TRUE(VerifyPose(*target, source, Matrix4::Identity()).verified());
}

// A stop requested during the rival search ends the registration cancelled, not verified.
TEST(AutoMethodTest, TheRivalSearchCanBeCancelled) {
  std::vector<double> pillars;
  for (double x = -18.0; x <= 18.0; x += 2.0) pillars.push_back(x);
  auto target = Target::Build(Corridor(pillars, 20.0, 0.01, 1)).value();
  bool stop = false;
  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [&](const IterationReport& r) {
    stop = stop || r.stage == Stage::kRival;
  };
  callbacks.should_stop = [&] { return stop; };
  auto result =
      Register(*target, Corridor(pillars, 15.0, 0.01, 2), Matrix4::Identity(), {}, callbacks);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(stop);
  EXPECT_EQ(result->termination, Termination::kCancelled);
  EXPECT_FALSE(result->auto_report->verified);
}

// Pillars at irregular spacing, the same scan: the probes along the corridor come back to the
// truth or end at poses that explain clearly less, and the result verifies.
TEST(AutoMethodTest, PillarsThatDoNotRepeatLeaveNoRival) {
  const std::vector<double> pillars = {-17.0, -12.2, -9.6, -4.1, -1.3, 1.4, 6.8, 9.6, 13.9, 17.5};
  auto target = Target::Build(Corridor(pillars, 20.0, 0.01, 1)).value();
  auto result = Register(*target, Corridor(pillars, 15.0, 0.01, 2), Matrix4::Identity(), {});
  ASSERT_TRUE(result.ok()) << result.status();
  const AutoReport& report = result->auto_report.value();
  EXPECT_TRUE(report.verified) << VerdictName(report.verification.verdict);
  EXPECT_FALSE(report.rival.has_value());
  // The search ran: the pose rests on the pillars' few samples along x.
  const auto probes =
      std::count_if(report.candidates.begin(), report.candidates.end(),
                    [](const AutoCandidate& c) { return c.origin == CandidateOrigin::kRival; });
  EXPECT_EQ(probes, 4);
  // A probe that came back to the result cannot be a rival: it was not verified again and
  // carries the result's score (verified). One that ended elsewhere was verified, and did not.
  int came_back = 0;
  for (const AutoCandidate& c : report.candidates) {
    if (c.origin != CandidateOrigin::kRival) continue;
    came_back += c.in_start_basin;
    EXPECT_EQ(c.score.verified(), c.in_start_basin) << VerdictName(c.score.verdict);
  }
  EXPECT_GE(came_back, 1);
  EXPECT_LT(result->transform.col(3).head<3>().norm(), 0.05);
}

// The finish follows the clouds' measured noise (registration/finish.h): plane-to-plane on clean
// samples of a bumpy sheet, MLS when both clouds carry 0.6 or 2 d of noise. Each polishes the
// verified pose over every source point, says which ran and why, and is more accurate than
// auto without it. Below 1 d the verified voxel alignment goes to the finish directly; at 2 d
// MLS-SICP refines it first.
TEST(AutoMethodTest, TheFinishFollowsTheNoiseAndPolishesTheVerifiedPose) {
  const double d =
      Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1)).value()->sampling_distance();
  const Matrix4 truth = RandomPerturbation(12.0, 0.1, Vec3::Zero(), 3);
  for (const double noise_d : {0.0, 0.6, 2.0}) {
    SCOPED_TRACE(noise_d);
    std::shared_ptr<const Target> target =
        Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, noise_d * d)).value();
    const PointCloud source =
        Transformed(SampleBumpySurface(12'000, -0.8, 0.6, 2, noise_d * d), truth.inverse());
    const Matrix4 start = RandomPerturbation(3.0, 3.0 * d, Vec3::Zero(), 4) * truth;
    std::vector<Stage> stages;
    RegistrationCallbacks callbacks;
    callbacks.on_iteration = [&](const IterationReport& r) { stages.push_back(r.stage); };
    RegistrationOptions options;
    auto polished = Register(*target, source, start, options, callbacks);
    options.automatic.finish = false;
    auto refined = Register(*target, source, start, options);
    ASSERT_TRUE(polished.ok()) << polished.status();
    ASSERT_TRUE(refined.ok()) << refined.status();
    ASSERT_TRUE(polished->verification.has_value() && polished->verification->verified());

    const FinishReport& finish = polished->auto_report->finish;
    EXPECT_EQ(finish.kind, noise_d == 0.0 ? FinishKind::kPlaneToPlane : FinishKind::kMls);
    EXPECT_EQ(finish.kind, ChooseFinish(finish.noise_d));
    // The verified voxel alignment goes straight to the finish below kRefineBeforeMlsFinishD;
    // at 2 d MLS-SICP refines it on its samples first.
    const bool refined_first =
        std::find(stages.begin(), stages.end(), Stage::kStart) != stages.end();
    EXPECT_EQ(RefinesBeforeFinish(finish.noise_d), noise_d == 2.0);
    EXPECT_EQ(refined_first, noise_d == 2.0);
    EXPECT_EQ(finish.noise_d, std::max(polished->target_noise_d, polished->source_noise_d));
    EXPECT_EQ(finish.crossover_d, kMlsFitFloorD);
    EXPECT_EQ(finish.samples, 12'000);  // every source point
    EXPECT_TRUE(finish.kept);
    ASSERT_FALSE(stages.empty());
    EXPECT_EQ(stages.back(), Stage::kFinish);
    EXPECT_EQ(refined->auto_report->finish.kind, FinishKind::kNone);

    ASSERT_EQ(polished->termination, Termination::kConverged);
    const PoseError with = EvaluatePose(source.points, polished->transform, truth, d);
    const PoseError without = EvaluatePose(source.points, refined->transform, truth, d);
    std::printf(
        "noise %.1f d: RMSE %.6f d with the finish (%d its, moved %.6f d), %.6f d without\n",
        noise_d, with.rmse_d, finish.iterations, finish.moved / d, without.rmse_d);
    EXPECT_LT(with.rmse_d, without.rmse_d);
  }
}

TEST(AutoMethodTest, TheMlsFinishMatchesAgainOnlyTheSamplesItsFirstIterationKept) {
  // A noisy source reaching a sixth beyond the target: the MLS finish's first iteration finds
  // no partner for the samples outside the overlap and refuses some by curvature; those are not
  // matched again and keep their fates in every later count, so the counts always sum to the
  // finish's samples, no later iteration matches more, and the pose is the truth's.
  const double d =
      Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1)).value()->sampling_distance();
  const double noise = 2.0 * d;
  const Matrix4 truth = RandomPerturbation(8.0, 0.05, Vec3::Zero(), 5);
  std::shared_ptr<const Target> target =
      Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, noise)).value();
  const PointCloud source =
      Transformed(SampleBumpySurface(12'000, -0.9, 1.2, 2, noise), truth.inverse());
  const Matrix4 start = RandomPerturbation(2.0, 2.0 * d, Vec3::Zero(), 6) * truth;
  std::vector<IterationReport> finish_reports;
  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [&](const IterationReport& r) {
    if (r.stage == Stage::kFinish) finish_reports.push_back(r);
  };
  auto result = Register(*target, source, start, {}, callbacks);
  ASSERT_TRUE(result.ok()) << result.status();
  const FinishReport& finish = result->auto_report->finish;
  ASSERT_EQ(finish.kind, FinishKind::kMls);
  ASSERT_TRUE(finish.kept);
  ASSERT_GE(finish_reports.size(), 3u);
  const CorrespondenceCounts& first = finish_reports.front().counts;
  EXPECT_GT(first.invalid, finish.samples / 10);  // the samples beyond the target
  for (const IterationReport& r : finish_reports) {
    SCOPED_TRACE(r.iteration);
    EXPECT_EQ(r.counts.total(), finish.samples);
    EXPECT_LE(r.counts.matched, first.matched);
    EXPECT_GE(r.counts.invalid, first.invalid);
    EXPECT_GE(r.counts.rejected_curvature, first.rejected_curvature);
  }
  const PoseError error = EvaluatePose(source.points, result->transform, truth, d);
  EXPECT_LT(error.translation_d, 1.0);
  EXPECT_LT(error.rotation_deg, 0.5);
}

// A stop requested in each stage ends the registration there: cancelled, with the report so far.
TEST(AutoMethodTest, EveryStageCanBeCancelled) {
  const BunnyPair& bunny = Bunny();
  const Matrix4 start = PerturbedStart(bunny.source, bunny.truth, bunny.target->sampling_distance(),
                                       {180.0, 30.0, 2});
  for (Stage stop_at : {Stage::kCoarse, Stage::kStart, Stage::kGlobal, Stage::kCandidate,
                        Stage::kFinal, Stage::kFinish}) {
    SCOPED_TRACE(std::string(StageName(stop_at)));
    bool stop = false;
    int reports_after_stop = 0;
    RegistrationCallbacks callbacks;
    callbacks.on_iteration = [&](const IterationReport& r) {
      if (stop) ++reports_after_stop;
      if (r.stage == stop_at) stop = true;
    };
    callbacks.should_stop = [&] { return stop; };
    // A verified candidate goes straight to the plane-to-plane finish; without a finish it is
    // refined (Stage::kFinal).
    RegistrationOptions options;
    options.automatic.finish = stop_at != Stage::kFinal;
    auto result = Register(*bunny.target, bunny.source, start, options, callbacks);
    ASSERT_TRUE(result.ok()) << result.status();
    EXPECT_EQ(result->termination, Termination::kCancelled);
    ASSERT_TRUE(result->auto_report.has_value());
    EXPECT_FALSE(result->auto_report->verified);
    EXPECT_LE(reports_after_stop, 1);
  }
}

}  // namespace
}  // namespace mlsreg
