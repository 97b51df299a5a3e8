#include "mlsreg/registration/registration.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cctype>

#include "absl/strings/str_cat.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/mls_radius.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

using testing::SampleBumpySurface;

// Target: 20k samples of the bumpy surface over [-1, 1]^2 (d ~ 0.007). Source: an independent
// sampling (so no point coincides) of the overlapping part [-0.8, 0.6]^2, moved by a known motion.
struct SyntheticPair {
  std::shared_ptr<const Target> target;
  PointCloud source;  // in its own frame
  Matrix4 truth;      // source -> target
};

SyntheticPair MakePair(double noise_d) {
  SyntheticPair pair;
  PointCloud target_cloud = SampleBumpySurface(20000, -1.0, 1.0, 1);
  auto target = Target::Build(std::move(target_cloud));
  EXPECT_TRUE(target.ok());
  pair.target = *target;
  const double d = pair.target->sampling_distance();
  PointCloud in_target_frame = SampleBumpySurface(12000, -0.8, 0.6, 2, noise_d * d);
  // truth maps source -> target, so the source is inv(truth) applied to target-frame samples.
  pair.truth = RandomPerturbation(12.0, 0.1, Vec3(0.0, 0.0, 0.0), 3);
  const Matrix4 inverse = pair.truth.inverse();
  for (const Vec3& p : in_target_frame.points) {
    pair.source.points.push_back(inverse.topLeftCorner<3, 3>() * p +
                                 inverse.topRightCorner<3, 1>());
  }
  return pair;
}

// The pair's truth moved by 5 degrees and 5 d (about a point near the overlap's middle): the
// start most tests register from.
Matrix4 StartFiveDegreesOff(const SyntheticPair& pair) {
  const double d = pair.target->sampling_distance();
  return RandomPerturbation(5.0, 5.0 * d, Vec3(-0.1, -0.1, 0.0), 4) * pair.truth;
}

// A parameterised test's name: the method's name without its punctuation (`cpsicp`).
std::string MethodTestName(const ::testing::TestParamInfo<Method>& info) {
  std::string name;
  for (char c : MethodName(info.param)) {
    if (std::isalnum(static_cast<unsigned char>(c))) name += c;
  }
  return name;
}

class RegistrationMethodTest : public ::testing::TestWithParam<Method> {};

TEST_P(RegistrationMethodTest, RecoversKnownTransformOfSyntheticPair) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  RegistrationOptions options;
  options.method = GetParam();
  const Matrix4 initial = StartFiveDegreesOff(pair);
  auto result = Register(*pair.target, pair.source, initial, options);
  ASSERT_TRUE(result.ok()) << result.status();
  const PoseError e = EvaluatePose(pair.source.points, result->transform, pair.truth, d);
  EXPECT_LT(e.rmse_d, 0.5) << MethodName(GetParam());
  EXPECT_LT(e.rotation_deg, 0.1);
  EXPECT_GE(result->iterations, 2);
  EXPECT_EQ(static_cast<int>(result->trace.size()), result->iterations);
  // The correspondence RMSE shrinks as the registration converges.
  EXPECT_LT(result->trace.back().rmse, result->trace.front().rmse);
}

// The same scans in other units and far from the origin (a national grid's coordinates, 5,000
// km away) register the same: every length is the data's own, and each step turns the samples
// about their centroid with rotations measured in their own length. Linearised about the origin,
// G-ICP at a thousandth of the units and 5,000 km away saw rotations as translations and stopped
// 5-10 degrees off.
class RegistrationUnitsTest : public ::testing::TestWithParam<Method> {};

TEST_P(RegistrationUnitsTest, ScansInOtherUnitsOrFarFromTheOriginRegisterTheSame) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  RegistrationOptions options;
  options.method = GetParam();
  Matrix4 initial = StartFiveDegreesOff(pair);
  // Its rotation as printed to 6 digits: orthonormal to 2e-6. Corrected about the origin, the
  // start 5,000 km away would move by 10 m.
  initial(0, 1) += 2e-6;
  auto reference = Register(*pair.target, pair.source, initial, options);
  ASSERT_TRUE(reference.ok()) << reference.status();
  struct Frame {
    double scale;
    Vec3 offset;
  };
  for (const Frame& frame : {Frame{1e3, Vec3::Zero()}, Frame{1e-3, Vec3::Zero()},
                             Frame{1.0, Vec3(512345.0, 5403210.0, 250.0)}}) {
    // The data mapped by p -> scale p + offset; a transform (R, t) becomes (R, scale t + offset -
    // R offset) there.
    const auto to_frame = [&](const Matrix4& t) {
      Matrix4 out = t;
      out.topRightCorner<3, 1>() = frame.scale * t.topRightCorner<3, 1>() + frame.offset -
                                   t.topLeftCorner<3, 3>() * frame.offset;
      return out;
    };
    const auto from_frame = [&](const Matrix4& t) {
      Matrix4 out = t;
      out.topRightCorner<3, 1>() =
          (t.topRightCorner<3, 1>() - frame.offset + t.topLeftCorner<3, 3>() * frame.offset) /
          frame.scale;
      return out;
    };
    const auto map = [&](const PointCloud& cloud) {
      PointCloud out;
      for (const Vec3& p : cloud.points) out.points.push_back(frame.scale * p + frame.offset);
      return out;
    };
    auto target = Target::Build(map(pair.target->cloud()));
    ASSERT_TRUE(target.ok()) << target.status();
    auto result = Register(**target, map(pair.source), to_frame(initial), options);
    ASSERT_TRUE(result.ok()) << result.status();
    const Matrix4 back = from_frame(result->transform);
    const std::string where =
        absl::StrCat(std::string(MethodName(GetParam())), " at scale ", frame.scale, ", offset ",
                     static_cast<double>(frame.offset.norm()));
    const PoseError truth_error = EvaluatePose(pair.source.points, back, pair.truth, d);
    EXPECT_LT(truth_error.rmse_d, 0.5) << where;
    EXPECT_LT(truth_error.rotation_deg, 0.1) << where;
    ASSERT_TRUE(result->verification.has_value()) << where;
    EXPECT_EQ(result->verification->verdict, reference->verification->verdict) << where;
    if (frame.offset.isZero()) {
      // The same grids and steps up to rounding: the same pose.
      const PoseError apart = EvaluatePose(pair.source.points, back, reference->transform, d);
      EXPECT_LT(apart.rmse_d, 0.01) << where;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, RegistrationUnitsTest,
                         ::testing::Values(Method::kAuto, Method::kCpSicp, Method::kMlsSicp,
                                           Method::kGicp),
                         MethodTestName);

// The local methods that work on any target refine to well below d. FGR (global, coarse) and
// reverse calibration (needs an organised target) have their own tests.
std::vector<Method> LocalMethods() {
  std::vector<Method> local;
  for (Method m : AllMethods()) {
    if (m != Method::kFgr && m != Method::kRcBl && m != Method::kRcP) local.push_back(m);
  }
  return local;
}

INSTANTIATE_TEST_SUITE_P(AllMethods, RegistrationMethodTest, ::testing::ValuesIn(LocalMethods()),
                         MethodTestName);

TEST(RegistrationTest, TwoPhaseRunsClosestPointThenMlsInOneTrace) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  RegistrationOptions options;
  options.method = Method::kCpThenMlsSicp;
  const Matrix4 initial = RandomPerturbation(5.0, 5.0 * d, Vec3::Zero(), 8) * pair.truth;
  std::vector<int> seen;
  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [&](const IterationReport& r) { seen.push_back(r.iteration); };
  auto result = Register(*pair.target, pair.source, initial, options, callbacks);
  ASSERT_TRUE(result.ok());
  // Iterations are numbered 1..n across both phases; phase 1 ran unfiltered (nothing rejected
  // by normal or curvature).
  ASSERT_EQ(static_cast<int>(seen.size()), result->iterations);
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], static_cast<int>(i) + 1);
  EXPECT_EQ(result->trace.front().counts.rejected_normal, 0);
  EXPECT_EQ(result->trace.front().counts.rejected_curvature, 0);
  EXPECT_GE(result->iterations, 3);
}

TEST(RegistrationTest, StSicpMatchesAgainstTheDenoisedTarget) {
  // Noise of 2 d on the target only: ST-SICP smooths the target onto its MLS surface first, so at
  // the true pose its closest points lie much nearer the (noise-free) source than CP-SICP's.
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  auto noisy = Target::Build(SampleBumpySurface(20000, -1.0, 1.0, 1, 2.0 * d));
  ASSERT_TRUE(noisy.ok());
  RegistrationOptions options;
  options.max_iterations = 1;
  options.mls.radius_d = 8.0;
  // A noise-free source (H ~ 0) against a noisy target (H ~ 0.02) fails every curvature-ratio
  // test; this test is about where the partners lie, so compare without it.
  options.filter.min_curvature_ratio = 0.0;
  options.method = Method::kCpSicp;
  auto cp = Register(**noisy, pair.source, pair.truth, options);
  options.method = Method::kStSicp;
  auto st = Register(**noisy, pair.source, pair.truth, options);
  ASSERT_TRUE(cp.ok() && st.ok());
  // Measured 0.75: the normal-direction noise is gone, the tangential gap to the nearest
  // (smoothed) sample remains.
  EXPECT_LT(st->trace.front().rmse, 0.85 * cp->trace.front().rmse);
  EXPECT_DOUBLE_EQ(st->sampling_distance, (*noisy)->sampling_distance());
}

TEST(RegistrationTest, MlsBeatsClosestPointOnNoisySamples) {
  // Noise of 2 d along z: MLS correspondences de-noise the target, closest points do not.
  const SyntheticPair pair = MakePair(2.0);
  const double d = pair.target->sampling_distance();
  // Add the same level of noise to the target by rebuilding it from noisy samples.
  auto noisy_target = Target::Build(SampleBumpySurface(20000, -1.0, 1.0, 1, 2.0 * d));
  ASSERT_TRUE(noisy_target.ok());
  RegistrationOptions options;
  options.mls.radius_d = 8.0;  // paper Table 2 for high noise
  const Matrix4 initial = RandomPerturbation(3.0, 3.0 * d, Vec3::Zero(), 5) * pair.truth;
  options.method = Method::kMlsSicp;
  auto mls = Register(**noisy_target, pair.source, initial, options);
  options.method = Method::kCpSicp;
  auto cp = Register(**noisy_target, pair.source, initial, options);
  ASSERT_TRUE(mls.ok() && cp.ok());
  const double mls_error = EvaluatePose(pair.source.points, mls->transform, pair.truth, d).rmse_d;
  const double cp_error = EvaluatePose(pair.source.points, cp->transform, pair.truth, d).rmse_d;
  EXPECT_LT(mls_error, 1.0);
  EXPECT_LT(mls_error, cp_error);
}

TEST(RegistrationTest, MlsFinePhaseProjectsOnlySamplesThatCanStillBeMatched) {
  // MLS-SICP at 1 d of noise, the source reaching a sixth beyond the target: the coarse phase
  // (patches, far queries seeded from their nearest sample) converges, then the fine phase
  // drops the samples whose partners are refused (first under the last coarse partners, then
  // under its own first match's) and keeps counting them as they were. Every iteration's counts
  // sum to the samples; no fine iteration matches more than the first (the first with far
  // queries dropped, so invalid); the pose is the truth's.
  const double d =
      Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1)).value()->sampling_distance();
  const Matrix4 truth = RandomPerturbation(8.0, 0.05, Vec3::Zero(), 5);
  auto target = Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, 1.0 * d));
  ASSERT_TRUE(target.ok());
  PointCloud source;
  const Matrix4 inverse = truth.inverse();
  for (const Vec3& p : SampleBumpySurface(12'000, -0.9, 1.2, 2, 1.0 * d).points) {
    source.points.push_back(inverse.topLeftCorner<3, 3>() * p + inverse.topRightCorner<3, 1>());
  }
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  const Matrix4 initial = RandomPerturbation(3.0, 3.0 * d, Vec3::Zero(), 6) * truth;
  auto result = Register(**target, source, initial, options);
  ASSERT_TRUE(result.ok()) << result.status();
  std::size_t fine = 0;
  while (fine < result->trace.size() && result->trace[fine].counts.invalid == 0) ++fine;
  ASSERT_GE(fine, 1u) << "no coarse phase";
  ASSERT_LT(fine + 2, result->trace.size()) << "no fine phase of 3 iterations";
  const int first_fine_matched = result->trace[fine].counts.matched;
  EXPECT_GT(result->trace[fine].counts.invalid, result->num_samples / 40);  // beyond the target
  for (std::size_t i = 0; i < result->trace.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(result->trace[i].counts.total(), result->num_samples);
    if (i > fine) {
      EXPECT_LE(result->trace[i].counts.matched, first_fine_matched);
    }
  }
  const PoseError e = EvaluatePose(source.points, result->transform, truth, d);
  EXPECT_LT(e.rmse_d, 0.5);
  EXPECT_LT(e.rotation_deg, 0.25);
}

TEST(RegistrationTest, CoarsePhaseFiltersFollowTheirPolicy) {
  // A noisy pair 10 degrees off. The fine phase always rejects by normal and by curvature; the
  // coarse phase (far queries seeded from samples) by both by default (the paper), by normal
  // only with kNormal, by neither with kNone.
  const SyntheticPair pair = MakePair(2.0);
  const double d = pair.target->sampling_distance();
  auto noisy_target = Target::Build(SampleBumpySurface(20000, -1.0, 1.0, 1, 2.0 * d));
  ASSERT_TRUE(noisy_target.ok());
  const Matrix4 initial = RandomPerturbation(10.0, 10.0 * d, Vec3::Zero(), 6) * pair.truth;
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  options.mls.radius_d = 8.0;
  auto run = [&] {
    auto r = Register(**noisy_target, pair.source, initial, options);
    EXPECT_TRUE(r.ok()) << r.status();
    EXPECT_GE(r->trace.size(), 2u);
    EXPECT_LT(EvaluatePose(pair.source.points, r->transform, pair.truth, d).rmse_d, 1.0);
    return *std::move(r);
  };
  const RegistrationResult all = run();
  EXPECT_GT(all.trace.front().counts.rejected_normal, 0);
  EXPECT_GT(all.trace.front().counts.rejected_curvature, 0);

  options.filter.coarse_phase = CoarsePhaseFilters::kNormal;
  const RegistrationResult normal = run();
  EXPECT_GT(normal.trace.front().counts.rejected_normal, 0);
  EXPECT_EQ(normal.trace.front().counts.rejected_curvature, 0);
  EXPECT_GT(normal.trace.back().counts.rejected_curvature, 0);

  options.filter.coarse_phase = CoarsePhaseFilters::kNone;
  const RegistrationResult none = run();
  EXPECT_EQ(none.trace.front().counts.rejected_normal, 0);
  EXPECT_EQ(none.trace.front().counts.rejected_curvature, 0);
  EXPECT_GT(none.trace.back().counts.rejected_curvature, 0);

  // Without a coarse phase (paper Algorithm 1: far queries dropped) both act throughout.
  options.mls.far_queries = FarQueryPolicy::kDrop;
  EXPECT_GT(run().trace.front().counts.rejected_curvature, 0);
}

TEST(RegistrationTest, ObserverSeesEveryIterationAndCancelStopsWithinOne) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  const Matrix4 initial = RandomPerturbation(5.0, 5.0 * d, Vec3::Zero(), 6) * pair.truth;
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  options.convergence_d = 0.0;  // never converge: run until cancelled
  options.stall_d = 0.0;
  options.stall_noise_fraction = 0.0;
  options.stall_standard_errors = 0.0;
  std::vector<int> seen;
  RegistrationCallbacks callbacks;
  callbacks.on_iteration = [&](const IterationReport& r) {
    seen.push_back(r.iteration);
    EXPECT_EQ(r.counts.total(), 2000);
    EXPECT_GT(r.counts.matched, 0);
    EXPECT_GE(r.elapsed_seconds, 0.0);
  };
  callbacks.should_stop = [&] { return seen.size() >= 3; };
  auto result = Register(*pair.target, pair.source, initial, options, callbacks);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->termination, Termination::kCancelled);
  EXPECT_EQ(seen, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(result->iterations, 3);
}

TEST(RegistrationTest, StSicpCanBeCancelledWhileSmoothingTheTarget) {
  // Smoothing the 20k-point target asks should_stop every 4096 points; the second ask says
  // stop, so no ICP iteration runs (were it asked only per iteration, one would).
  const SyntheticPair pair = MakePair(0.0);
  RegistrationOptions options;
  options.method = Method::kStSicp;
  options.mls.radius_d = 5.0;  // explicit: no noise estimate asks first
  int asked = 0;
  RegistrationCallbacks callbacks;
  callbacks.should_stop = [&] { return ++asked >= 2; };
  auto result = Register(*pair.target, pair.source, pair.truth, options, callbacks);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_EQ(result->termination, Termination::kCancelled);
  EXPECT_EQ(result->iterations, 0);
  EXPECT_TRUE(result->trace.empty());
  EXPECT_EQ(asked, 2);
  EXPECT_TRUE(result->transform.isApprox(pair.truth, 1e-9));
}

TEST(RegistrationTest, SameInputsGiveBitIdenticalResults) {
  const SyntheticPair pair = MakePair(0.0);
  const Matrix4 initial = pair.truth;
  RegistrationOptions options;
  options.max_iterations = 5;
  auto a = Register(*pair.target, pair.source, initial, options);
  auto b = Register(*pair.target, pair.source, initial, options);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->transform, b->transform);
}

// A length in metres is the same registration as that length in units of the target's d.
TEST(RegistrationTest, LengthsInMetresAreTheSameAsInUnitsOfD) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  const Matrix4 initial = RandomPerturbation(3.0, 3.0 * d, Vec3::Zero(), 5) * pair.truth;
  RegistrationOptions in_d;
  in_d.method = Method::kMlsSicp;
  in_d.max_iterations = 8;
  in_d.filter.max_distance_d = 6.0;
  in_d.mls.radius_d = 5.0;
  RegistrationOptions in_metres = in_d;
  in_metres.filter.max_distance_d = 0.0;
  in_metres.absolute_lengths = {{"filter.max_distance_d", 6.0 * d}, {"mls.radius_d", 5.0 * d}};
  auto a = Register(*pair.target, pair.source, initial, in_d);
  auto b = Register(*pair.target, pair.source, initial, in_metres);
  ASSERT_TRUE(a.ok() && b.ok()) << b.status();
  EXPECT_TRUE(b->transform.isApprox(a->transform, 1e-9));
  EXPECT_NEAR(b->scales.mls_radius, 5.0 * d, 1e-12);
  // The result reports each length given in metres and what it came to in d.
  EXPECT_TRUE(a->scales.user_lengths.empty());
  ASSERT_EQ(b->scales.user_lengths.size(), 2u);
  EXPECT_EQ(b->scales.user_lengths[0].parameter, "filter.max_distance_d");
  EXPECT_DOUBLE_EQ(b->scales.user_lengths[0].value, 6.0 * d);
  EXPECT_NEAR(b->scales.user_lengths[0].value_d, 6.0, 1e-12);
  EXPECT_EQ(b->scales.user_lengths[1].parameter, "mls.radius_d");
  EXPECT_NEAR(b->scales.user_lengths[1].value_d, 5.0, 1e-12);

  // Too large a radius for this target is refused with both units and d.
  in_metres.absolute_lengths = {{"mls.radius_d", 1000.0 * d}};
  auto c = Register(*pair.target, pair.source, initial, in_metres);
  EXPECT_EQ(c.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(c.status().message().find("mls.radius_d"), std::string::npos) << c.status();
  EXPECT_NE(c.status().message().find("1000 d on this target"), std::string::npos) << c.status();
  in_metres.absolute_lengths = {{"num_samples", 1.0}};
  EXPECT_NE(Register(*pair.target, pair.source, initial, in_metres)
                .status()
                .message()
                .find("num_samples is not a length parameter"),
            std::string::npos);
}

TEST(RegistrationTest, RejectsBadInputNamingTheField) {
  const SyntheticPair pair = MakePair(0.0);
  RegistrationOptions options;
  Matrix4 scaled = Matrix4::Identity() * 2.0;
  scaled(3, 3) = 1.0;
  auto r1 = Register(*pair.target, pair.source, scaled, options);
  EXPECT_EQ(r1.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r1.status().message().find("initial_transform"), std::string::npos);

  options.mls.radius_d = -1;
  auto r2 = Register(*pair.target, pair.source, Matrix4::Identity(), options);
  EXPECT_NE(r2.status().message().find("mls.radius_d"), std::string::npos);

  PointCloud bad = pair.source;
  bad.points[7].x() = std::numeric_limits<double>::quiet_NaN();
  auto r3 = Register(*pair.target, bad, Matrix4::Identity(), RegistrationOptions{});
  EXPECT_EQ(r3.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(r3.status().message().find("source: point 7"), std::string::npos);

  EXPECT_EQ(ParseMethod("icp").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(*ParseMethod("mls-sicp"), Method::kMlsSicp);
}

TEST(TargetTest, RejectsTooSmallAndNonFiniteClouds) {
  PointCloud tiny;
  tiny.points = {Vec3(0, 0, 0), Vec3(1, 0, 0)};
  EXPECT_EQ(Target::Build(tiny).status().code(), absl::StatusCode::kInvalidArgument);
  PointCloud same(testing::SampleBumpySurface(100, -1, 1, 1));
  for (Vec3& p : same.points) p = Vec3(1, 2, 3);
  auto status = Target::Build(same).status();
  EXPECT_NE(status.message().find("sampling distance"), std::string::npos);
}

// The automatic radius follows the noise: the source carries 2 d of noise (along z, close to the
// normal of the gentle test surface), so r = 4 sigma = 8 d; noise-free it is the 5 d floor; an
// explicit radius is used as given, with no estimate when nothing else needs one.
TEST(AutoRadiusTest, ARegistrationAtTwoDOfNoisePicksEightD) {
  const SyntheticPair noisy = MakePair(2.0);
  RegistrationOptions options;
  options.method = Method::kMlsSicp;  // radius auto
  auto result = Register(*noisy.target, noisy.source, noisy.truth, options);
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_TRUE(result->mls_radius_auto);
  EXPECT_NEAR(result->source_noise_d, 2.0, 0.3);
  EXPECT_LT(result->target_noise_d, 0.2);
  EXPECT_NEAR(result->mls_radius_d, 8.0, 1.2);

  const SyntheticPair clean = MakePair(0.0);
  auto floor = Register(*clean.target, clean.source, clean.truth, options);
  ASSERT_TRUE(floor.ok());
  EXPECT_EQ(floor->mls_radius_d, kMinAutoMlsRadiusD);

  options.mls.radius_d = 6.5;
  options.verify = false;  // the verification's band needs the source's noise too
  auto given = Register(*noisy.target, noisy.source, noisy.truth, options);
  ASSERT_TRUE(given.ok());
  EXPECT_FALSE(given->mls_radius_auto);
  EXPECT_EQ(given->mls_radius_d, 6.5);
  EXPECT_EQ(given->source_noise_d, 0.0);  // not estimated
  EXPECT_FALSE(given->verification.has_value());
}

// Every MLS projection recovers the transform of the synthetic pair; the default (patches, then
// exact in the fine phase) ends within 0.05 d of the exact projection's pose, the patches alone
// within 0.2 d.
TEST(MlsProjectionTest, EveryProjectionRecoversTheTransform) {
  const SyntheticPair pair = MakePair(0.0);
  const double d = pair.target->sampling_distance();
  const Matrix4 initial = StartFiveDegreesOff(pair);
  ASSERT_NE(pair.target->mls_patches(), nullptr);
  Matrix4 transforms[3];
  for (MlsProjectionKind kind : {MlsProjectionKind::kPatchesThenExact, MlsProjectionKind::kPatches,
                                 MlsProjectionKind::kExact}) {
    RegistrationOptions options;
    options.mls.projection = kind;
    auto result = Register(*pair.target, pair.source, initial, options);
    ASSERT_TRUE(result.ok()) << result.status();
    const PoseError e = EvaluatePose(pair.source.points, result->transform, pair.truth, d);
    EXPECT_LT(e.rmse_d, 0.5) << static_cast<int>(kind);
    EXPECT_TRUE(result->converged);
    transforms[static_cast<int>(kind)] = result->transform;
  }
  const Matrix4& exact = transforms[static_cast<int>(MlsProjectionKind::kExact)];
  EXPECT_LT(EvaluatePose(pair.source.points, transforms[0], exact, d).rmse_d, 0.05);
  EXPECT_LT(EvaluatePose(pair.source.points, transforms[1], exact, d).rmse_d, 0.2);
}

// Threads split the work, never change it: every parallel method gives bit-identical
// transforms and traces for 1, 2 and 3 threads, and a target builds the same.
// Every method at sigma = 0.8 d (auto finishes by MLS there), and auto and G-ICP on clean data
// (auto's plane-to-plane finish).
TEST(ThreadsTest, ResultsAreBitIdenticalForAnyThreadCount) {
  const SyntheticPair noisy = MakePair(0.8);
  const SyntheticPair clean = MakePair(0.0);
  const std::vector<std::pair<const SyntheticPair*, Method>> cases = {
      {&noisy, Method::kAuto},   {&noisy, Method::kMlsSicp}, {&noisy, Method::kCpSicp},
      {&noisy, Method::kStSicp}, {&noisy, Method::kGicp},    {&noisy, Method::kCpThenMlsSicp},
      {&clean, Method::kAuto},   {&clean, Method::kGicp}};
  for (const auto& [problem, method] : cases) {
    const SyntheticPair& pair = *problem;
    const double d = pair.target->sampling_distance();
    const Matrix4 initial = RandomPerturbation(8.0, 5.0 * d, Vec3::Zero(), 4) * pair.truth;
    SCOPED_TRACE(std::string(MethodName(method)) + (problem == &clean ? " clean" : " noisy"));
    RegistrationOptions options;
    options.method = method;
    options.max_iterations = 15;
    auto one = Register(*pair.target, pair.source, initial, options, {}, ExecutionOptions{1});
    ASSERT_TRUE(one.ok());
    for (int threads : {2, 3}) {
      auto many =
          Register(*pair.target, pair.source, initial, options, {}, ExecutionOptions{threads});
      ASSERT_TRUE(many.ok());
      EXPECT_EQ(many->transform, one->transform) << threads << " threads";
      ASSERT_EQ(many->trace.size(), one->trace.size());
      for (std::size_t i = 0; i < one->trace.size(); ++i) {
        EXPECT_EQ(many->trace[i].rmse, one->trace[i].rmse);
        EXPECT_EQ(many->trace[i].counts.matched, one->trace[i].counts.matched);
      }
      // The verdict's evidence too (its passes find the samples' surface in parallel).
      ASSERT_TRUE(one->verification && many->verification);
      EXPECT_EQ(many->verification->verdict, one->verification->verdict);
      EXPECT_EQ(many->verification->inliers, one->verification->inliers);
      EXPECT_EQ(many->verification->rmse_d, one->verification->rmse_d);
      EXPECT_EQ(many->verification->settle_displacement, one->verification->settle_displacement);
      EXPECT_EQ(many->verification->coherent_residual, one->verification->coherent_residual);
    }
  }
  TargetOptions three;
  three.threads = 3;
  auto a = Target::Build(noisy.target->cloud());
  auto b = Target::Build(noisy.target->cloud(), three);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ((*a)->surface().normals, (*b)->surface().normals);
  EXPECT_EQ((*a)->surface().curvature, (*b)->surface().curvature);
  EXPECT_EQ((*a)->sampling_distance(), (*b)->sampling_distance());
  EXPECT_EQ((*a)->scales().median_spacing, (*b)->scales().median_spacing);
  EXPECT_EQ((*a)->scales().spacing_p90, (*b)->scales().spacing_p90);
}

}  // namespace
}  // namespace mlsreg
