// Closed-form and linearised weighted rigid-motion estimators used inside Sparse ICP.
#pragma once

#include <Eigen/Geometry>
#include <span>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

using RigidTransform = Eigen::Isometry3d;

// Rotation exp([omega]x) (Rodrigues), exact for any angle.
Eigen::Matrix3d ExpSo3(const Vec3& omega);

// The rigid increment of a Gauss-Newton step over (omega, v): x' = exp([omega]x) x + v, with the
// exact SO(3) exponential.
RigidTransform TwistIncrement(const Eigen::Matrix<double, 6, 1>& omega_v);

// The same step taken about `centre`: x' = exp([omega]x) (x - centre) + centre + v. A step
// linearised about the samples' centroid is conditioned the same wherever the data's origin lies;
// about an origin far from the data (a scan in a national grid, millions of units away) every
// rotation looks like a translation and the constrained solve below drops it.
RigidTransform TwistIncrementAbout(const Eigen::Matrix<double, 6, 1>& omega_v, const Vec3& centre);

// Solves the 6x6 normal equations h * step = rhs of a Gauss-Newton step over (omega, v), moving
// only along directions the data constrain: eigen-directions whose eigenvalue is at most 1e-9 of
// the largest get no motion (e.g. the in-plane translations and the rotation about the normal
// when every correspondence lies on one plane, where a plain LDLT solve returns steps of 1e10
// units). The test is made with the rotations measured in a length of the data's own (the
// square root of the ratio of h's rotation and translation traces: about the samples' RMS
// distance from the centre), so that it answers the same in any unit: in radians, a street in
// millimetres (rotations 1e9 times as informative as translations) or a statue in kilometres
// (1e-9 times) would lose real directions. Zero when h is zero or not finite.
Eigen::Matrix<double, 6, 1> SolveConstrainedStep(const Eigen::Matrix<double, 6, 6>& h,
                                                 const Eigen::Matrix<double, 6, 1>& rhs);

// argmin_{R,t} sum_i w_i |R x_i + t - y_i|^2 (weighted Kabsch/Umeyama, det-corrected).
// Entries with w_i = 0 are ignored; identity when the total weight is zero.
RigidTransform PointToPointMotion(std::span<const Vec3> x, std::span<const Vec3> y,
                                  std::span<const double> w);

// One Gauss-Newton step of argmin_{R,t} sum_i w_i (n_i . (R x_i + t - y_i) - u_i)^2, linearised
// in the rotation about the weighted centroid of x, with the rotation rebuilt by the exact SO(3)
// exponential. Directions the planes do not constrain get no motion (SolveConstrainedStep);
// identity when the total weight is zero.
//
// With tangential_weight = lambda > 0 the objective gains lambda * |P_i (R x_i + t - y_i)|^2,
// P_i = I - n_i n_i^T: the part of each residual along the tangent plane. For correspondences
// that are foot points on a smooth surface (MLS), that part starts near zero, so the term only
// damps sliding along the surface, which the planes alone constrain through curvature.
RigidTransform PointToPlaneMotion(std::span<const Vec3> x, std::span<const Vec3> y,
                                  std::span<const Vec3> n, std::span<const double> u,
                                  std::span<const double> w, double tangential_weight = 0.0);

// The sums PointToPlaneMotion solves, about a centre c given in advance (its weighted centroid
// of x there): added one correspondence at a time, in any blocks (Merge adds another block's),
// then solved. What lets a solver build them on several threads, and in the same pass that
// makes the correspondences' targets.
struct PointToPlaneSums {
  Eigen::Matrix<double, 6, 6> lhs = Eigen::Matrix<double, 6, 6>::Zero();  // lower triangle
  Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix3d moments = Eigen::Matrix3d::Zero();  // the tangential term's, lower triangle
  double tangential_total = 0.0;
  int count = 0;

  // One correspondence: xc = x - c, e = x - y, its normal n, target offset u and weight w > 0.
  void Add(const Vec3& xc, const Vec3& e, const Vec3& n, double u, double w,
           double tangential_weight);
  void Merge(const PointToPlaneSums& other);
  // The motion about `centre` (identity when nothing was added).
  RigidTransform Solve(const Vec3& centre) const;
};

}  // namespace mlsreg
