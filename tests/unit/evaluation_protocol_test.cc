// The evaluation's start-pose protocol is one function: `register --perturb-*` and `eval` share it.
#include <gtest/gtest.h>

#include "mlsreg/evaluation/evaluation.h"
#include "mlsreg/evaluation/metrics.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

TEST(PerturbedStartTest, RotatesAboutThePlacedCentroidByTheAngleAndMovesByTheDistance) {
  const PointCloud source = testing::SampleBumpySurface(500, -1, 1, 9);
  Matrix4 initial = Matrix4::Identity();
  initial.topRightCorner<3, 1>() = Vec3(5, -2, 1);
  const double d = 0.01;
  const PerturbationProtocol protocol{10.0, 10.0, 7};
  const Matrix4 start = PerturbedStart(source, initial, d, protocol);
  const PoseError error = EvaluatePose(source.points, start, initial, d);
  EXPECT_NEAR(error.rotation_deg, 10.0, 1e-9);
  // The rotation is about the centroid as `initial` places it: the centroid moves by the
  // translation alone.
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : source.points) centroid += p;
  centroid /= static_cast<double>(source.size());
  const Vec3 placed = initial.topLeftCorner<3, 3>() * centroid + initial.topRightCorner<3, 1>();
  const Vec3 moved = start.topLeftCorner<3, 3>() * centroid + start.topRightCorner<3, 1>();
  EXPECT_NEAR((moved - placed).norm(), 10.0 * d, 1e-12);
  // Deterministic per (seed, index); problem 0 is what `register` uses.
  EXPECT_EQ(PerturbedStart(source, initial, d, protocol, 0), start);
  EXPECT_NE(PerturbedStart(source, initial, d, protocol, 1), start);
  EXPECT_EQ(PerturbedStart(source, initial, d, {0.0, 0.0, 7}), initial);
}

}  // namespace
}  // namespace mlsreg
