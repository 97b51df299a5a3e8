// The columns of the formats whose files may not name their fields: XYZ/CSV text (the header
// line is optional) and NPY arrays. What each column holds comes from names (a header line, or
// ReadOptions::columns) or, without names, from the column count and the data; TableCloud then
// turns rows of numbers into a validated cloud and the notes that say how they were read.
// Not part of the public API (io_xyz.cc and io_npy.cc use it).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "io_internal.h"
#include "mlsreg/io/io.h"

namespace mlsreg::io_internal {

enum class ColumnRole : std::uint8_t {
  kX,
  kY,
  kZ,
  kNormalX,
  kNormalY,
  kNormalZ,
  kRed,
  kGreen,
  kBlue,
  kIgnored,
  // Columns 4-6 of six unnamed columns: normals or colours, as the data decide.
  kUndecided,
};

struct ColumnLayout {
  std::vector<ColumnRole> roles;   // one per column
  std::vector<std::string> names;  // as named (lower case), or "column N" when unnamed
  std::string origin;              // where the names came from ("the header line"); empty: none
  bool has_normals = false;
  bool has_colors = false;
};

// The layout `names` give: x, y, z (required); nx ny nz or normal_x normal_y normal_z; r g b or
// red green blue (each group all three or none); any other name is a column read and ignored.
// Names are case-insensitive; a leading "//" (CloudCompare's header) is dropped. InvalidArgument
// naming `origin` for a missing axis, a name given twice or an incomplete group.
absl::StatusOr<ColumnLayout> LayoutFromNames(const std::vector<std::string>& names,
                                             std::string_view origin);

// The layout of `count` unnamed columns: x y z, then normals or colours for six columns (decided
// from the data by TableCloud), ignored columns for any other count. InvalidArgument below 3.
absl::StatusOr<ColumnLayout> LayoutFromCount(std::size_t count);

// A cloud built row by row from a table of numbers with a layout.
class TableCloud {
 public:
  TableCloud(std::string_view format, ColumnLayout layout);

  void Reserve(std::uint64_t rows);
  // One row of layout().roles.size() values; errors name `where`.
  absl::Status AddRow(const double* values, const Location& where);
  // The cloud and the notes saying how its columns were read (also for unnamed columns whose
  // meaning came from the data); InvalidArgument when six unnamed columns fit neither reading.
  absl::StatusOr<CloudFile> Finish() &&;

  const ColumnLayout& layout() const { return layout_; }
  std::size_t size() const { return cloud_.points.size(); }

 private:
  std::string_view format_;
  ColumnLayout layout_;
  PointCloud cloud_;
  std::vector<std::array<float, 3>> colors_;  // as read; scaled to bytes in Finish
  float max_color_ = 0.0f;
  bool fractional_color_ = false;
  const bool undecided_columns_;  // six unnamed columns
  std::vector<Vec3> undecided_;   // their columns 4-6
  bool all_unit_ = true;
  bool all_bytes_ = true;
  std::uint64_t first_not_unit_ = 0;  // row
};

}  // namespace mlsreg::io_internal
