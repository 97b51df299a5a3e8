// The pose covariance every verification reports (VerificationScore::pose_covariance).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "mlsreg/core/transform.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/registration/verification.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

using testing::SampleBumpySurface;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

Matrix6 RandomSpd(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Matrix<double, 6, 12> a;
  for (int i = 0; i < a.size(); ++i) a.data()[i] = g(rng);
  return a * a.transpose() + 0.1 * Matrix6::Identity();
}

// How a small motion xi = (rotation vector, translation) about `about` moves the point y.
Eigen::Matrix<double, 3, 6> DisplacementJacobian(const Vec3& y, const Vec3& about, double lever) {
  const Vec3 r = y - about;
  Eigen::Matrix3d minus_cross;  // omega -> omega x r = -[r]x omega
  minus_cross << 0.0, r.z(), -r.y(), -r.z(), 0.0, r.x(), r.y(), -r.x(), 0.0;
  Eigen::Matrix<double, 3, 6> j;
  j << minus_cross / lever, Eigen::Matrix3d::Identity();
  return j;
}

TEST(PoseCovarianceTest, IndependentResidualsGiveTheirVarianceOverTheInformation) {
  const Matrix6 information = RandomSpd(1);
  const double variance = 0.04;
  const std::optional<Matrix6> covariance =
      PoseCovariance(information, variance * information, Vec3::Zero(), 1.0);
  ASSERT_TRUE(covariance.has_value());
  const Matrix6 expected = variance * information.inverse();
  EXPECT_LT((*covariance - expected).norm(), 1e-9 * expected.norm());
}

// The covariance is evidence gathered about a centre, with rotations scaled by a lever, and is
// reported about the target's origin: every point must then move alike in either frame.
TEST(PoseCovarianceTest, EveryPointMovesAlikeAboutTheCentreAndAboutTheOrigin) {
  const Matrix6 information = RandomSpd(2), spread = RandomSpd(3);
  const Vec3 centre(3.0, -2.0, 5.0);
  const double lever = 2.5;
  const std::optional<Matrix6> at_origin = PoseCovariance(information, spread, centre, lever);
  ASSERT_TRUE(at_origin.has_value());
  const Matrix6 at_centre = information.inverse() * spread * information.inverse();
  for (const Vec3& y : {Vec3(0, 0, 0), Vec3(3, -2, 5), Vec3(10, 4, -7), Vec3(-1, 8, 2)}) {
    const Eigen::Matrix3d moved_origin = DisplacementJacobian(y, Vec3::Zero(), 1.0) * *at_origin *
                                         DisplacementJacobian(y, Vec3::Zero(), 1.0).transpose();
    const Eigen::Matrix3d moved_centre = DisplacementJacobian(y, centre, lever) * at_centre *
                                         DisplacementJacobian(y, centre, lever).transpose();
    EXPECT_LT((moved_origin - moved_centre).norm(), 1e-9 * moved_centre.norm()) << y.transpose();
  }
}

TEST(PoseCovarianceTest, NoneWhenADirectionHasNoEvidence) {
  Matrix6 information = RandomSpd(4);
  const Eigen::SelfAdjointEigenSolver<Matrix6> solver(information);
  // Remove the information along one direction (a slide along a bare road).
  const Eigen::Matrix<double, 6, 1> v = solver.eigenvectors().col(2);
  information -= solver.eigenvalues()[2] * v * v.transpose();
  EXPECT_FALSE(PoseCovariance(information, information, Vec3::Zero(), 1.0).has_value());
}

// Two noisy samplings of a bumpy sheet at the true pose: the covariance grows with the noise, a
// little faster than in proportion: at 4 times the noise the residuals are 4 times larger, and
// neighbours share more of them (the MLS radius follows the noise: 26 % of the residual RMS
// shared at 0.005, 65 % at 0.02), which the sandwich counts.
TEST(PoseCovarianceTest, ASheetsCovarianceGrowsWithItsNoise) {
  const auto sigma_at = [](double noise) {
    auto target = Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, 1, noise)).value();
    const VerificationScore score =
        VerifyPose(*target, SampleBumpySurface(20'000, -1.0, 1.0, 2, noise), Matrix4::Identity());
    EXPECT_TRUE(score.verified()) << VerdictName(score.verdict);
    EXPECT_TRUE(score.pose_covariance.has_value());
    return score.pose_translation_sigma;
  };
  const double quiet = sigma_at(0.005), noisy = sigma_at(0.02);
  EXPECT_GT(quiet, 0.0);
  EXPECT_GT(noisy / quiet, 3.5);
  EXPECT_LT(noisy / quiet, 10.0);
}

// The registration's actual error, measured against the exact truth, lies within what its
// covariance allows: xi^T C^-1 xi under chi-square(6)'s 99.9 % point, for several noise draws.
TEST(PoseCovarianceTest, TheRegistrationsErrorLiesWithinItsCovariance) {
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    const double noise = 0.01;
    auto target = Target::Build(SampleBumpySurface(20'000, -1.0, 1.0, seed, noise)).value();
    const PointCloud source = SampleBumpySurface(20'000, -1.0, 1.0, seed + 100, noise);
    const Matrix4 start = RandomPerturbation(3.0, 0.05, Vec3::Zero(), seed);
    const absl::StatusOr<RegistrationResult> result =
        Register(*target, source, start, RegistrationOptions{});
    ASSERT_TRUE(result.ok()) << result.status();
    ASSERT_TRUE(result->verification.has_value());
    ASSERT_TRUE(result->verification->verified()) << VerdictName(result->verification->verdict);
    ASSERT_TRUE(result->verification->pose_covariance.has_value());
    // The truth is the identity: exp(xi) * result = identity.
    const Matrix4 error = result->transform.inverse();
    const Eigen::AngleAxisd turn(Eigen::Matrix3d(error.topLeftCorner<3, 3>()));
    Eigen::Matrix<double, 6, 1> xi;
    xi << turn.angle() * turn.axis(), error.topRightCorner<3, 1>();
    const double m2 = xi.dot(result->verification->pose_covariance->ldlt().solve(xi));
    EXPECT_LT(m2, 22.46) << "seed " << seed << " error " << xi.transpose();
    EXPECT_GT(result->verification->pose_translation_sigma, 0.0);
  }
}

}  // namespace
}  // namespace mlsreg
