#include "mlsreg/io/pose_files.h"

#include <Eigen/Geometry>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "mlsreg/io/io.h"

namespace mlsreg {
namespace {

std::string FileName(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

bool IsConf(const std::string& path) { return std::filesystem::path(path).extension() == ".conf"; }

std::vector<std::string> Fields(std::string_view line) {
  std::vector<std::string> fields;
  std::string current;
  for (char c : line) {
    if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
      if (!current.empty()) fields.push_back(std::move(current));
      current.clear();
    } else {
      current += c;
    }
  }
  if (!current.empty()) fields.push_back(std::move(current));
  return fields;
}

bool ToDouble(const std::string& text, double* value) {
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(text.data(), end, *value);
  return ec == std::errc() && ptr == end && std::isfinite(*value);
}

template <typename Visit>
void ForEachLine(std::string_view text, Visit visit) {
  int number = 0;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    ++number;
    visit(number, text.substr(start, end - start));
    start = end + 1;
  }
}

}  // namespace

absl::StatusOr<std::vector<Matrix4>> ParsePoseRows(std::string_view text, std::size_t count) {
  std::vector<Matrix4> poses;
  absl::Status status;
  ForEachLine(text, [&](int number, std::string_view line) {
    if (!status.ok()) return;
    const std::vector<std::string> fields = Fields(line);
    if (fields.empty() || fields[0][0] == '#') return;
    const std::string where = absl::StrCat("poses line ", number);
    if (fields.size() != 16) {
      status = absl::InvalidArgumentError(
          absl::StrCat(where, ": ", fields.size(), " numbers, expected 16 (a row-major 4x4)"));
      return;
    }
    Matrix4 m;
    for (int k = 0; k < 16; ++k) {
      if (!ToDouble(fields[k], &m(k / 4, k % 4))) {
        status = absl::InvalidArgumentError(
            absl::StrCat(where, ": '", fields[k], "' is not a finite number"));
        return;
      }
    }
    if (absl::Status s = CheckRigid(m, where); !s.ok()) {
      status = s;
      return;
    }
    poses.push_back(Orthonormalize(m));
  });
  if (!status.ok()) return status;
  if (poses.size() != count) {
    return absl::InvalidArgumentError(
        absl::StrCat("poses: ", poses.size(), " poses for ", count, " scans"));
  }
  return poses;
}

absl::StatusOr<std::vector<Matrix4>> ParseStanfordConf(std::string_view text,
                                                       const std::vector<std::string>& scan_paths) {
  std::map<std::string, Matrix4> by_name;
  absl::Status status;
  ForEachLine(text, [&](int number, std::string_view line) {
    if (!status.ok()) return;
    const std::vector<std::string> fields = Fields(line);
    if (fields.empty() || fields[0] != "bmesh") return;  // camera, mesh, comments
    const std::string where = absl::StrCat("conf line ", number);
    double v[7];
    bool ok = fields.size() == 9;
    for (int k = 0; ok && k < 7; ++k) ok = ToDouble(fields[2 + k], &v[k]);
    if (!ok) {
      status = absl::InvalidArgumentError(
          absl::StrCat(where, ": expected 'bmesh FILE tx ty tz qi qj qk qr'"));
      return;
    }
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);  // (w, x, y, z)
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      status = absl::InvalidArgumentError(absl::StrCat(where, ": the quaternion is not unit"));
      return;
    }
    Matrix4 m = Matrix4::Identity();
    m.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix().transpose();
    m.topRightCorner<3, 1>() = Vec3(v[0], v[1], v[2]);
    by_name[fields[1]] = m;
  });
  if (!status.ok()) return status;
  std::vector<Matrix4> poses;
  for (const std::string& path : scan_paths) {
    const auto it = by_name.find(FileName(path));
    if (it == by_name.end()) {
      return absl::InvalidArgumentError(
          absl::StrCat("poses: the .conf has no 'bmesh ", FileName(path), "' line"));
    }
    poses.push_back(it->second);
  }
  return poses;
}

absl::StatusOr<std::vector<Matrix4>> ReadPoses(const std::string& path,
                                               const std::vector<std::string>& scan_paths) {
  auto text = ReadFileBytes(path);
  if (!text.ok()) return text.status();
  auto poses =
      IsConf(path) ? ParseStanfordConf(*text, scan_paths) : ParsePoseRows(*text, scan_paths.size());
  if (!poses.ok()) {
    return absl::Status(poses.status().code(), absl::StrCat(path, ": ", poses.status().message()));
  }
  return poses;
}

std::string FormatPoseRows(const std::vector<Matrix4>& poses) {
  std::string out =
      "# one pose per scan, in scan order: 16 row-major numbers mapping the scan into the common "
      "frame\n";
  for (const Matrix4& m : poses) {
    for (int k = 0; k < 16; ++k) {
      absl::StrAppendFormat(&out, "%s%.12g", k ? " " : "", m(k / 4, k % 4));
    }
    out += "\n";
  }
  return out;
}

std::string FormatStanfordConf(const std::vector<Matrix4>& poses,
                               const std::vector<std::string>& scan_paths) {
  std::string out;
  for (std::size_t i = 0; i < poses.size() && i < scan_paths.size(); ++i) {
    // The file's rotation is R(q)^T: write the conjugate of the pose's quaternion.
    const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::Matrix3d(poses[i].topLeftCorner<3, 3>()))
                                     .normalized()
                                     .conjugate();
    absl::StrAppendFormat(&out, "bmesh %s %.12g %.12g %.12g %.12g %.12g %.12g %.12g\n",
                          FileName(scan_paths[i]), poses[i](0, 3), poses[i](1, 3), poses[i](2, 3),
                          q.x(), q.y(), q.z(), q.w());
  }
  return out;
}

absl::Status WritePoses(const std::string& path, const std::vector<Matrix4>& poses,
                        const std::vector<std::string>& scan_paths) {
  std::ofstream out(path, std::ios::binary);
  out << (IsConf(path) ? FormatStanfordConf(poses, scan_paths) : FormatPoseRows(poses));
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  return absl::OkStatus();
}

}  // namespace mlsreg
