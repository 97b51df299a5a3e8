// Rigid 4x4 transforms at the boundary: parsing, validation, formatting, seeded perturbations.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

using Matrix4 = Eigen::Matrix4d;

// OK when `m` is finite, its last row is (0 0 0 1) and its 3x3 block is a rotation (orthonormal,
// det +1) within `tolerance`. The message names `field` and what is wrong.
absl::Status CheckRigid(const Matrix4& m, std::string_view field, double tolerance = 1e-4);

// The nearest rigid transform: the 3x3 block projected onto SO(3) (SVD), the translation set so
// that `about` lands where `m` puts it. A rotation printed to 6-10 digits is orthonormal to about
// 1e-6; corrected about the origin, it would move data 5,000 km from the origin (a national
// grid's coordinates) by metres, so callers correct it about their data (Register: the source's
// centroid; the verification: its samples').
Matrix4 Orthonormalize(const Matrix4& m, const Vec3& about = Vec3::Zero());

// The centroid of `points` (zero when there are none).
Vec3 Centroid(const std::vector<Vec3>& points);

// 16 numbers in row-major order, separated by whitespace and/or commas, or the path of a file
// holding them, checked with CheckRigid (orthonormal to 1e-4, so 6-8 printed digits are enough)
// and returned as written: the registration and the verification correct the rotation about the
// data they move (Orthonormalize). Errors name `field`.
absl::StatusOr<Matrix4> ParseTransform(std::string_view text_or_path, std::string_view field);

// 16 row-major numbers separated by spaces, full double precision.
std::string FormatTransform(const Matrix4& m);

// A seeded random rigid motion about `center`: rotation of exactly `angle_deg` about a uniformly
// random axis through `center`, then a translation of exactly `translation` (absolute units) in a
// uniformly random direction. Deterministic for a given seed on every platform.
Matrix4 RandomPerturbation(double angle_deg, double translation, const Vec3& center,
                           std::uint64_t seed);

// The RMS distance between `points` moved by `a` and by `b` (0 for no points).
double RmsDistanceBetween(const std::vector<Vec3>& points, const Matrix4& a, const Matrix4& b);

}  // namespace mlsreg
