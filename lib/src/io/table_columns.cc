#include "table_columns.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace mlsreg::io_internal {
namespace {

struct NamedRole {
  std::string_view name;
  ColumnRole role;
};

constexpr NamedRole kNames[] = {
    {"x", ColumnRole::kX},
    {"y", ColumnRole::kY},
    {"z", ColumnRole::kZ},
    {"nx", ColumnRole::kNormalX},
    {"ny", ColumnRole::kNormalY},
    {"nz", ColumnRole::kNormalZ},
    {"normal_x", ColumnRole::kNormalX},
    {"normal_y", ColumnRole::kNormalY},
    {"normal_z", ColumnRole::kNormalZ},
    {"r", ColumnRole::kRed},
    {"g", ColumnRole::kGreen},
    {"b", ColumnRole::kBlue},
    {"red", ColumnRole::kRed},
    {"green", ColumnRole::kGreen},
    {"blue", ColumnRole::kBlue},
};

ColumnRole RoleOf(std::string_view name) {
  for (const NamedRole& entry : kNames) {
    if (entry.name == name) return entry.role;
  }
  return ColumnRole::kIgnored;
}

// The names of a group of three roles, as a message shows them.
constexpr std::string_view kGroupNames[] = {"x, y, z", "nx, ny, nz", "r, g, b"};

// Every unit vector an 8-digit text or float32 file holds is unit to this tolerance.
constexpr double kUnitTolerance = 1e-4;

bool IsByte(double v) { return v >= 0.0 && v <= 255.0 && v == std::floor(v); }

std::uint8_t ToByte(float v, bool unit_scale) {
  const float scaled = unit_scale ? v * 255.0f : v;
  return static_cast<std::uint8_t>(std::clamp(std::lround(scaled), 0L, 255L));
}

// "intensity (column 4), label (column 7)".
std::string IgnoredColumns(const ColumnLayout& layout, bool named) {
  std::vector<std::string> parts;
  for (std::size_t c = 0; c < layout.roles.size(); ++c) {
    if (layout.roles[c] != ColumnRole::kIgnored) continue;
    parts.push_back(named ? absl::StrCat(layout.names[c], " (column ", c + 1, ")")
                          : absl::StrCat(c + 1));
  }
  return absl::StrJoin(parts, ", ");
}

}  // namespace

absl::StatusOr<ColumnLayout> LayoutFromNames(const std::vector<std::string>& names,
                                             std::string_view origin) {
  ColumnLayout layout;
  layout.origin = std::string(origin);
  int found[9] = {};
  for (const std::string& given : names) {
    std::string name = absl::AsciiStrToLower(given);
    if (name.rfind("//", 0) == 0) name.erase(0, 2);
    const ColumnRole role = RoleOf(name);
    if (role != ColumnRole::kIgnored) {
      if (found[static_cast<int>(role)]++ > 0) {
        return absl::InvalidArgumentError(absl::StrCat(layout.origin, " names column '", name,
                                                       "' twice (or under two of its names)"));
      }
    }
    layout.roles.push_back(role);
    layout.names.push_back(std::move(name));
  }
  for (int group = 0; group < 3; ++group) {
    const int present = found[3 * group] + found[3 * group + 1] + found[3 * group + 2];
    if (group == 0 && present < 3) {
      return absl::InvalidArgumentError(absl::StrCat(
          layout.origin, " (", absl::StrJoin(layout.names, " "), ") does not name x, y and z"));
    }
    if (present != 0 && present != 3) {
      return absl::InvalidArgumentError(
          absl::StrCat(layout.origin, " (", absl::StrJoin(layout.names, " "),
                       ") names only some of ", ToAbsl(kGroupNames[group]), ": all three or none"));
    }
  }
  layout.has_normals = found[3] > 0;
  layout.has_colors = found[6] > 0;
  return layout;
}

absl::StatusOr<ColumnLayout> LayoutFromCount(std::size_t count) {
  if (count < 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("has ", count, " columns; at least 3 (x y z) are needed"));
  }
  ColumnLayout layout;
  for (std::size_t c = 0; c < count; ++c) {
    layout.roles.push_back(c < 3        ? static_cast<ColumnRole>(c)
                           : count == 6 ? ColumnRole::kUndecided
                                        : ColumnRole::kIgnored);
    layout.names.push_back(absl::StrCat("column ", c + 1));
  }
  return layout;
}

TableCloud::TableCloud(std::string_view format, ColumnLayout layout)
    : format_(format),
      layout_(std::move(layout)),
      undecided_columns_(std::find(layout_.roles.begin(), layout_.roles.end(),
                                   ColumnRole::kUndecided) != layout_.roles.end()) {}

void TableCloud::Reserve(std::uint64_t rows) {
  cloud_.points.reserve(rows);
  if (layout_.has_normals) cloud_.normals.reserve(rows);
  if (layout_.has_colors) colors_.reserve(rows);
  if (undecided_columns_) undecided_.reserve(rows);
}

absl::Status TableCloud::AddRow(const double* values, const Location& where) {
  PointValues point{};
  std::array<float, 3> color{};
  Vec3 undecided = Vec3::Zero();
  for (std::size_t c = 0; c < layout_.roles.size(); ++c) {
    const double v = values[c];
    const ColumnRole role = layout_.roles[c];
    switch (role) {
      case ColumnRole::kX:
      case ColumnRole::kY:
      case ColumnRole::kZ:
      case ColumnRole::kNormalX:
      case ColumnRole::kNormalY:
      case ColumnRole::kNormalZ:
        point[static_cast<int>(role)] = v;
        break;
      case ColumnRole::kRed:
      case ColumnRole::kGreen:
      case ColumnRole::kBlue:
        if (!(v >= 0.0 && v <= 255.0)) {
          return ErrorAt(where,
                         absl::StrCat("colour ", layout_.names[c], " is ", v, ", not in [0, 255]"));
        }
        color[static_cast<int>(role) - static_cast<int>(ColumnRole::kRed)] = static_cast<float>(v);
        max_color_ = std::max(max_color_, static_cast<float>(v));
        fractional_color_ |= v != std::floor(v);
        break;
      case ColumnRole::kUndecided:
        if (!std::isfinite(v)) {
          return ErrorAt(where, absl::StrCat(layout_.names[c], " is not finite (", v, ")"));
        }
        undecided[static_cast<int>(c) - 3] = v;
        all_bytes_ = all_bytes_ && IsByte(v);
        break;
      case ColumnRole::kIgnored:
        break;
    }
  }
  if (undecided_columns_) {
    if (all_unit_ && std::abs(undecided.norm() - 1.0) > kUnitTolerance) {
      all_unit_ = false;
      first_not_unit_ = cloud_.points.size();
    }
    undecided_.push_back(undecided);
  }
  if (absl::Status s = AppendPoint(point, layout_.has_normals, where, &cloud_); !s.ok()) return s;
  if (layout_.has_colors) colors_.push_back(color);
  return absl::OkStatus();
}

absl::StatusOr<CloudFile> TableCloud::Finish() && {
  CloudFile file;
  const bool named = !layout_.origin.empty();
  if (!undecided_.empty()) {
    if (all_unit_) {
      cloud_.normals.reserve(undecided_.size());
      for (std::size_t i = 0; i < undecided_.size(); ++i) {
        Vec3 normal = undecided_[i];
        const Location where = {format_, Location::Unit::kLine, 0, "point", i};
        if (absl::Status s = NormalizeNormal(where, &normal); !s.ok()) return s;
        cloud_.normals.push_back(normal);
      }
      file.notes.push_back(
          absl::StrCat(ToAbsl(format_),
                       ": 6 unnamed columns: columns 4-6 read as normals nx ny nz (every row is a "
                       "unit vector); a header line or the columns option names them otherwise"));
    } else if (all_bytes_) {
      cloud_.colors.reserve(undecided_.size());
      for (const Vec3& v : undecided_) {
        cloud_.colors.push_back({static_cast<std::uint8_t>(v[0]), static_cast<std::uint8_t>(v[1]),
                                 static_cast<std::uint8_t>(v[2])});
      }
      file.notes.push_back(
          absl::StrCat(ToAbsl(format_),
                       ": 6 unnamed columns: columns 4-6 read as colours r g b (every value is an "
                       "integer from 0 to 255); a header line or the columns option names them "
                       "otherwise"));
    } else {
      return absl::InvalidArgumentError(absl::StrCat(
          ToAbsl(format_), ": 6 unnamed columns, and columns 4-6 are neither normals (point ",
          first_not_unit_,
          " is not a unit vector) nor colours (integers from 0 to 255): name the columns in a "
          "header line (\"x y z nx ny nz\", \"x y z r g b\") or with the columns option"));
    }
  }
  if (layout_.has_colors) {
    const bool unit_scale = fractional_color_ && max_color_ <= 1.0f;
    cloud_.colors.reserve(colors_.size());
    for (const auto& c : colors_) {
      cloud_.colors.push_back(
          {ToByte(c[0], unit_scale), ToByte(c[1], unit_scale), ToByte(c[2], unit_scale)});
    }
    if (unit_scale) {
      file.notes.push_back(
          absl::StrCat(ToAbsl(format_), ": colours given in [0, 1], scaled to 0-255"));
    }
  }
  if (const std::string ignored = IgnoredColumns(layout_, named); !ignored.empty()) {
    file.notes.push_back(
        named ? absl::StrCat(ToAbsl(format_), ": columns read and ignored: ", ignored)
              : absl::StrCat(ToAbsl(format_), ": ", layout_.roles.size(),
                             " unnamed columns: the first three read as x y z, column",
                             layout_.roles.size() > 4 ? "s " : " ", ignored,
                             " ignored; a header line or the columns option names them"));
  }
  absl::StatusOr<PointCloud> cloud = FinishCloud(format_, std::move(cloud_));
  if (!cloud.ok()) return cloud.status();
  file.cloud = *std::move(cloud);
  return file;
}

}  // namespace mlsreg::io_internal
