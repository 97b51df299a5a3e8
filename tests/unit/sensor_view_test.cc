// The sensor of a scan found from its sampling (FindSensor), what that sensor could see
// (SensorView), and method auto's use of it: a street pose whose uncovered samples lie where the
// target's sensor could not see needs no global stage.
#include "mlsreg/geometry/sensor_view.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "gtest/gtest.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/registration.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

// An axis-aligned box.
struct Box {
  Vec3 lo, hi;
};

// A street 16-18 m wide between facades 8 m tall from x = -60 to 60, parked cars and lamp posts,
// and a spinning sensor 1.7 m above the road: 66 beams from -24 to +2 degrees, 0.5 degree azimuth
// steps, returns up to `max_range` from the sensor, range noise `noise`. Points are in the
// sensor's frame (sensor at the origin), as a LiDAR writes them.
PointCloud SpinningScan(const Vec3& sensor, double max_range, double noise, std::uint64_t seed) {
  // Facades in blocks of irregular length, every other block set back by 1.2 m.
  std::vector<Box> boxes;
  const std::vector<double> left = {-60, -47, -38, -22, -13, 2, 9, 24, 31, 45, 60};
  const std::vector<double> right = {-60, -51, -35, -28, -10, -1, 13, 27, 36, 52, 60};
  for (std::size_t k = 0; k + 1 < left.size(); ++k) {
    const double back = (k % 2) * 1.2;
    boxes.push_back({{left[k], 8.0 + back, -1.7}, {left[k + 1], 8.5 + back, 6.3}});
  }
  for (std::size_t k = 0; k + 1 < right.size(); ++k) {
    const double back = ((k + 1) % 2) * 1.2;
    boxes.push_back({{right[k], -8.5 - back, -1.7}, {right[k + 1], -8.0 - back, 6.3}});
  }
  for (const double x : {-41.0, -23.0, -14.5, 3.0, 11.0, 26.5, 37.0}) {  // cars, right side
    boxes.push_back({{x, -7.8, -1.7}, {x + 4.2, -6.0, -0.2}});
  }
  for (const double x : {-33.0, -8.0, 7.5, 19.0, 44.0}) {  // left side
    boxes.push_back({{x, 6.0, -1.7}, {x + 4.5, 7.8, -0.3}});
  }
  for (const double x : {-52.0, -37.5, -29.0, -17.0, -4.5, 1.0, 15.5, 23.0, 34.0, 48.5}) {
    boxes.push_back({{x, 5.5, -1.7}, {x + 0.3, 5.8, 4.3}});         // lamp posts, left kerb
    boxes.push_back({{x + 3.1, -8.0, 1.0}, {x + 4.6, -7.4, 6.3}});  // bays on the right facade
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  PointCloud scan;
  const double degree = std::numbers::pi / 180.0;
  for (double elevation = -24.0; elevation <= 2.0 + 1e-9; elevation += 0.4) {
    for (double azimuth = 0.0; azimuth < 360.0; azimuth += 0.5) {
      const Vec3 d(std::cos(elevation * degree) * std::cos(azimuth * degree),
                   std::cos(elevation * degree) * std::sin(azimuth * degree),
                   std::sin(elevation * degree));
      double nearest = max_range;
      if (d.z() < 0.0) nearest = std::min(nearest, (-1.7 - sensor.z()) / d.z());  // the road
      for (const Box& box : boxes) {                                              // slab test
        double enter = 0.0, leave = nearest;
        for (int axis = 0; axis < 3 && enter <= leave; ++axis) {
          if (std::abs(d[axis]) < 1e-12) {
            if (sensor[axis] < box.lo[axis] || sensor[axis] > box.hi[axis]) leave = -1.0;
            continue;
          }
          double a = (box.lo[axis] - sensor[axis]) / d[axis];
          double b = (box.hi[axis] - sensor[axis]) / d[axis];
          if (a > b) std::swap(a, b);
          enter = std::max(enter, a);
          leave = std::min(leave, b);
        }
        if (enter <= leave && enter > 0.0) nearest = std::min(nearest, enter);
      }
      if (nearest < max_range) scan.points.push_back(d * (nearest + gauss(rng)));
    }
  }
  return scan;
}

std::optional<SensorFinding> FindSensorOf(const std::vector<Vec3>& points) {
  const KdTree tree(points);
  return MeasureScales(points, tree).sensor;
}

TEST(SensorViewTest, AScanInItsSensorsFrameShowsTheSensorAndAnObjectDoesNot) {
  const PointCloud scan = SpinningScan(Vec3::Zero(), 60.0, 0.01, 1);
  const std::optional<SensorFinding> sensor = FindSensorOf(scan.points);
  ASSERT_TRUE(sensor.has_value());
  EXPECT_TRUE(sensor->position.isZero());
  // Neighbouring returns lie 0.4-0.5 degrees apart as the sensor sees them.
  EXPECT_GT(sensor->angular_step, 0.2 * std::numbers::pi / 180.0);
  EXPECT_LT(sensor->angular_step, 0.6 * std::numbers::pi / 180.0);

  // The same scan far from the origin (a map frame), and an object measured in its own frame.
  std::vector<Vec3> moved = scan.points;
  for (Vec3& p : moved) p += Vec3(1000.0, 0.0, 0.0);
  EXPECT_FALSE(FindSensorOf(moved).has_value());
  EXPECT_FALSE(FindSensorOf(testing::SampleSphere(20'000, 1.0, -0.5, 2).points).has_value());
  EXPECT_FALSE(FindSensorOf(testing::SampleBumpySurface(20'000, -1.0, 1.0, 3).points).has_value());
}

// The view of a noiseless street scan's sensor (at the origin), or nothing if none is found.
std::optional<SensorView> ViewOfNoiselessStreet() {
  const PointCloud scan = SpinningScan(Vec3::Zero(), 60.0, 0.0, 1);
  const std::optional<SensorFinding> sensor = FindSensorOf(scan.points);
  if (!sensor) return std::nullopt;
  return SensorView::Build(scan.points, *sensor);
}

TEST(SensorViewTest, APointBehindWhatTheSensorSawOrWhereItSawNothingIsHidden) {
  const std::optional<SensorView> view = ViewOfNoiselessStreet();
  ASSERT_TRUE(view.has_value());
  const double tolerance = 0.2;
  // Behind the car parked at x = 3-7.2 on the right: the ray to it crosses the car.
  EXPECT_TRUE(view->Hides(Vec3(6.5, -7.9, -1.0), tolerance));
  // In front of the left wall, in the open: the sensor's ray went on to the wall.
  EXPECT_FALSE(view->Hides(Vec3(1.0, 5.0, 0.0), tolerance));
  // On the road, where the sensor saw the road.
  EXPECT_FALSE(view->Hides(Vec3(2.0, 3.0, -1.7), tolerance));
  // Above the highest beam (+2 degrees): the sensor looks nowhere near it.
  EXPECT_TRUE(view->Hides(Vec3(3.0, 0.0, 3.0), tolerance));
  // Beyond the walls' far end along the street: no return came from that way within 60 m.
  EXPECT_TRUE(view->Hides(Vec3(70.0, 0.0, 0.5), tolerance));
  EXPECT_GT(view->MemoryBytes(), 0u);
}

TEST(SensorViewTest, APointInTheOpenWhereTheSensorSawFartherIsSeenThrough) {
  const std::optional<SensorView> view = ViewOfNoiselessStreet();
  ASSERT_TRUE(view.has_value());
  const double tolerance = 0.2;
  // In front of the left wall, in the open: the sensor's ray passed it and went on to the wall.
  EXPECT_TRUE(view->SeesThrough(Vec3(1.0, 5.0, 0.0), tolerance));
  // On the road, where the sensor saw the road, and 5 cm above it 8.5 m away (its ray meets the
  // road 0.3 farther, but the beams below it return nearer: the grazing road is not open space).
  EXPECT_FALSE(view->SeesThrough(Vec3(2.0, 3.0, -1.7), tolerance));
  EXPECT_FALSE(view->SeesThrough(Vec3(8.0, 3.0, -1.65), tolerance));
  // Behind the parked car: hidden, not seen through.
  EXPECT_FALSE(view->SeesThrough(Vec3(6.5, -7.9, -1.0), tolerance));
  // Above the highest beam: no return from that way says nothing.
  EXPECT_FALSE(view->SeesThrough(Vec3(3.0, 0.0, 3.0), tolerance));
}

// Two scans of the street `apart` metres apart along it, each in its own sensor's frame (range
// noise 1 cm, 40 m range): the target from the origin, the source from (apart, 0, 0), so the
// truth is that translation.
struct StreetPair {
  Vec3 source_sensor;
  PointCloud source;
  std::shared_ptr<const Target> target;
  Matrix4 truth = Matrix4::Identity();
};
StreetPair StreetPairApart(double apart) {
  StreetPair pair;
  pair.source_sensor = Vec3(apart, 0.0, 0.0);
  pair.source = SpinningScan(pair.source_sensor, 40.0, 0.01, 2);
  pair.target = Target::Build(SpinningScan(Vec3::Zero(), 40.0, 0.01, 3)).value();
  pair.truth.block<3, 1>(0, 3) = pair.source_sensor;
  return pair;
}

// Two scans 14 m apart along the street. Where the source sees past the target's range and
// behind the target's parked cars, the right pose covers little of it; those samples are hidden
// from the target's sensor, and from the right start auto ends without a global stage.
TEST(SensorViewTest, AutoAcceptsAStreetPoseWhoseUncoveredSamplesTheTargetCouldNotSee) {
  const auto [source_sensor, source, target, truth] = StreetPairApart(14.0);
  ASSERT_NE(target->sensor_view(), nullptr);

  absl::StatusOr<RegistrationResult> result = Register(*target, source, truth, {});
  ASSERT_TRUE(result.ok()) << result.status();
  ASSERT_TRUE(result->verification.has_value());
  const VerificationScore& score = *result->verification;
  EXPECT_TRUE(score.verified()) << VerdictName(score.verdict);
  const double accept = RegistrationOptions{}.automatic.accept_fraction;
  EXPECT_LT(score.covered_fraction(), accept);
  EXPECT_GT(score.hidden, 0);
  EXPECT_GE(score.visible_covered_fraction(), accept);
  EXPECT_LE(score.seen_through_fraction(), 0.01);  // at the truth only noise lies in the open
  ASSERT_TRUE(result->auto_report.has_value());
  EXPECT_TRUE(result->auto_report->early_exit);
  EXPECT_LT((result->transform.block<3, 1>(0, 3) - source_sensor).norm(), 0.05);
  ASSERT_TRUE(result->scales.sensor.has_value());
  EXPECT_TRUE(result->scales.sensor->isZero());
}

// The same street pair at the truth slid 3 m along the road: the ground and the facades still
// agree, but the source's parked cars and poles now stand where the target's beams passed and
// returned from the road and the walls beyond. The target's sensor saw through them.
TEST(SensorViewTest, AStreetPoseSlidAlongTheRoadIsSeenThrough) {
  const auto [source_sensor, source, target, truth] = StreetPairApart(14.0);
  const VerificationScore right = VerifyPose(*target, source, truth, /*threads=*/1);
  EXPECT_TRUE(right.verified()) << VerdictName(right.verdict);
  EXPECT_LE(right.seen_through_fraction(), 0.01);
  Matrix4 slid = truth;
  slid(0, 3) += 3.0;
  const VerificationScore wrong = VerifyPose(*target, source, slid, /*threads=*/1);
  EXPECT_EQ(wrong.verdict, Verdict::kSeenThrough) << VerdictName(wrong.verdict);
  EXPECT_GT(wrong.seen_through_fraction(), 0.03);
}

// Two scans of the street 10 m apart, registered from the identity (no prior): the road and the
// facades run along the street, and the start's refinement stops 10 m short, where they still
// lie on the target (it covers 85 % of what the target's sensor could see). The target's sensor
// saw through the source's cars and poles there, so the start does not verify; the global stage
// finds the truth, which is returned, verified.
TEST(SensorViewTest,
     AStreetPoseSlidAlongTheStreetFromTheIdentityIsRefusedAndTheGlobalStageFindsTheTruth) {
  const auto [source_sensor, source, target, truth] = StreetPairApart(10.0);

  absl::StatusOr<RegistrationResult> result = Register(*target, source, Matrix4::Identity(), {});
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_LT((result->transform.block<3, 1>(0, 3) - source_sensor).norm(), 0.05);
  ASSERT_TRUE(result->verification.has_value());
  EXPECT_TRUE(result->verification->verified()) << VerdictName(result->verification->verdict);
  const AutoReport& report = result->auto_report.value();
  EXPECT_FALSE(report.early_exit);
  ASSERT_GT(report.candidates.size(), 1u);
  const AutoCandidate& start = report.candidates[0];
  EXPECT_GT((start.refined.block<3, 1>(0, 3) - source_sensor).norm(), 5.0);  // along the street
  EXPECT_EQ(start.score.verdict, Verdict::kSeenThrough) << VerdictName(start.score.verdict);
  EXPECT_GT(start.score.seen_through_fraction(), 0.05);
  EXPECT_NE(report.chosen, 0);
}

// A street scan laid upside down, its road on the target's road (turned 180 degrees about the
// vertical plane along the street and lowered by twice the sensor's height): its facades go
// below the road, hidden from the target's sensor, and nothing lies where that sensor saw
// through. But the pose puts the source's sensor under the road: it would have seen the road
// from behind.
TEST(SensorViewTest, AStreetScanLaidUpsideDownOnTheRoadIsSeenFromBehind) {
  const auto [source_sensor, source, target, truth] = StreetPairApart(14.0);
  const VerificationScore right = VerifyPose(*target, source, truth, /*threads=*/1);
  EXPECT_TRUE(right.verified()) << VerdictName(right.verdict);
  EXPECT_GT(right.sides_judged, 500);
  EXPECT_LE(right.seen_from_behind_fraction(), 0.01);
  Matrix4 upside_down = Matrix4::Identity();
  upside_down.diagonal() << -1.0, 1.0, -1.0, 1.0;  // 180 degrees about y
  upside_down(2, 3) = -3.4;
  const VerificationScore wrong = VerifyPose(*target, source, truth * upside_down, /*threads=*/1);
  EXPECT_EQ(wrong.verdict, Verdict::kSeenFromBehind) << VerdictName(wrong.verdict);
  EXPECT_EQ(wrong.seen_through, 0);
}

// Registered from the identity, the global stage of that street pair (14 m apart) offers such a
// pose (13 m off, upside down), which passes every other test. It is refused, and a right
// candidate is returned, verified.
TEST(SensorViewTest, AutoRefusesTheUpsideDownStreetCandidateAndReturnsTheTruth) {
  const auto [source_sensor, source, target, truth] = StreetPairApart(14.0);
  absl::StatusOr<RegistrationResult> result = Register(*target, source, Matrix4::Identity(), {});
  ASSERT_TRUE(result.ok()) << result.status();
  EXPECT_LT((result->transform.block<3, 1>(0, 3) - source_sensor).norm(), 0.05);
  ASSERT_TRUE(result->verification.has_value());
  EXPECT_TRUE(result->verification->verified()) << VerdictName(result->verification->verdict);
  const AutoReport& report = result->auto_report.value();
  const bool refused_upside_down =
      std::any_of(report.candidates.begin(), report.candidates.end(), [](const AutoCandidate& c) {
        return c.score.verdict == Verdict::kSeenFromBehind && c.refined(2, 2) < 0.0;
      });
  EXPECT_TRUE(refused_upside_down);
}

}  // namespace
}  // namespace mlsreg
