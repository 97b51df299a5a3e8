#include "mlsreg/core/transform.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <charconv>
#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlsreg {

absl::Status CheckRigid(const Matrix4& m, std::string_view field, double tolerance) {
  const std::string name(field);
  if (!m.allFinite()) return absl::InvalidArgumentError(name + " has a non-finite entry");
  if (m.row(3).transpose() != Eigen::Vector4d(0, 0, 0, 1)) {
    return absl::InvalidArgumentError(name + " must have last row 0 0 0 1");
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double orthogonality =
      (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > tolerance) {
    return absl::InvalidArgumentError(absl::StrCat(
        name, " is not rigid: its rotation block is not orthonormal (max |R^T R - I| = ",
        orthogonality, ")"));
  }
  if (r.determinant() < 0.0) {
    return absl::InvalidArgumentError(name + " is a reflection (det < 0), not a rotation");
  }
  return absl::OkStatus();
}

Matrix4 Orthonormalize(const Matrix4& m, const Vec3& about) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0.0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    r = u * svd.matrixV().transpose();
  }
  Matrix4 out = Matrix4::Identity();
  out.topLeftCorner<3, 3>() = r;
  out.topRightCorner<3, 1>() = m.topRightCorner<3, 1>() + (m.topLeftCorner<3, 3>() - r) * about;
  return out;
}

Vec3 Centroid(const std::vector<Vec3>& points) {
  Vec3 sum = Vec3::Zero();
  for (const Vec3& p : points) sum += p;
  return points.empty() ? sum : Vec3(sum / static_cast<double>(points.size()));
}

namespace {
bool ParseNumbers(std::string_view text, std::vector<double>& out, std::string& bad_token) {
  std::size_t i = 0;
  while (i < text.size()) {
    const char c = text[i];
    if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == ',') {
      ++i;
      continue;
    }
    std::size_t end = i;
    while (end < text.size() && text[end] != ' ' && text[end] != '\t' && text[end] != '\n' &&
           text[end] != '\r' && text[end] != ',') {
      ++end;
    }
    const std::string_view token = text.substr(i, end - i);
    double value = 0.0;
    const char* first = token.data();
    if (*first == '+') ++first;
    const auto [ptr, ec] = std::from_chars(first, token.data() + token.size(), value);
    if (ec != std::errc() || ptr != token.data() + token.size()) {
      bad_token = std::string(token);
      return false;
    }
    out.push_back(value);
    i = end;
  }
  return true;
}
}  // namespace

absl::StatusOr<Matrix4> ParseTransform(std::string_view text_or_path, std::string_view field) {
  const std::string name(field);
  std::string text(text_or_path);
  std::vector<double> numbers;
  std::string bad_token;
  if (!ParseNumbers(text, numbers, bad_token)) {
    // Not numbers: try it as a file.
    std::ifstream file(text);
    if (!file) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": '", text, "' is neither 16 numbers nor a readable file"));
    }
    std::stringstream buffer;
    buffer << file.rdbuf();
    numbers.clear();
    if (!ParseNumbers(buffer.str(), numbers, bad_token)) {
      return absl::InvalidArgumentError(
          absl::StrCat(name, ": file '", text, "' holds a non-number '", bad_token, "'"));
    }
  }
  if (numbers.size() != 16) {
    return absl::InvalidArgumentError(
        absl::StrCat(name, " needs 16 numbers (row-major 4x4), got ", numbers.size()));
  }
  Matrix4 m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = numbers[4 * r + c];
  }
  if (absl::Status s = CheckRigid(m, name); !s.ok()) return s;
  return m;
}

std::string FormatTransform(const Matrix4& m) {
  std::string out;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!out.empty()) out += ' ';
      out += absl::StrFormat("%.17g", m(r, c));
    }
  }
  return out;
}

namespace {
// Uniform double in [0, 1) from 53 random bits; portable (unlike std::uniform_real_distribution).
double Uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

Vec3 RandomUnitVector(std::mt19937_64& rng) {
  const double z = 2.0 * Uniform01(rng) - 1.0;
  const double phi = 2.0 * std::numbers::pi * Uniform01(rng);
  const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vec3(s * std::cos(phi), s * std::sin(phi), z);
}
}  // namespace

Matrix4 RandomPerturbation(double angle_deg, double translation, const Vec3& center,
                           std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Vec3 axis = RandomUnitVector(rng);
  const Vec3 direction = RandomUnitVector(rng);
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, axis).toRotationMatrix();
  Matrix4 m = Matrix4::Identity();
  m.topLeftCorner<3, 3>() = r;
  m.topRightCorner<3, 1>() = center - r * center + translation * direction;
  return m;
}

double RmsDistanceBetween(const std::vector<Vec3>& points, const Matrix4& a, const Matrix4& b) {
  if (points.empty()) return 0.0;
  const Matrix4 difference = b - a;  // b p - a p, affine in p
  double sum = 0.0;
  for (const Vec3& p : points) {
    sum += (difference.topLeftCorner<3, 3>() * p + difference.topRightCorner<3, 1>()).squaredNorm();
  }
  return std::sqrt(sum / static_cast<double>(points.size()));
}

}  // namespace mlsreg
