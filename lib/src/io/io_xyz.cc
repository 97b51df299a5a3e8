// XYZ / CSV reader and writer: one point per line, "x y z" or "x y z nx ny nz". See mlsreg/io.h.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "io_internal.h"
#include "mlsreg/io/io.h"

namespace mlsreg {
namespace {

using io_internal::ErrorAt;
using io_internal::IsSpace;
using io_internal::Location;

constexpr std::string_view kXyz = "XYZ";

// Blank lines and lines whose first non-blank character is '#' carry no data.
bool IsBlankOrComment(std::string_view line) {
  for (char c : line) {
    if (!IsSpace(c)) return c == '#';
  }
  return true;
}

bool IsSeparator(char c) { return IsSpace(c) || c == ','; }

// True when no field of `line` is a number: the line is a header such as "x,y,z".
bool HasNoNumber(std::string_view line) {
  std::size_t pos = 0;
  while (pos < line.size()) {
    while (pos < line.size() && IsSeparator(line[pos])) ++pos;
    const std::size_t begin = pos;
    while (pos < line.size() && !IsSeparator(line[pos])) ++pos;
    if (pos > begin && io_internal::ParseDouble(line.substr(begin, pos - begin))) return false;
  }
  return true;
}

// The fields of one data line.
struct LineFields {
  static constexpr std::size_t kMaxKept = 6;
  std::array<std::string_view, kMaxKept> first;  // the first (up to) six fields
  std::size_t count = 0;                         // how many fields the line has in all
};

// Splits `line` into fields separated by whitespace and/or one comma. A comma with no field before
// or after it (",1,2", "1,,2", "1,2,") is an error: an empty field is a missing value.
absl::Status SplitFields(std::string_view line, const Location& where, LineFields* fields) {
  fields->count = 0;
  std::size_t pos = 0;
  const auto skip_spaces = [&] {
    while (pos < line.size() && IsSpace(line[pos])) ++pos;
  };
  skip_spaces();
  while (pos < line.size()) {
    if (line[pos] == ',') return ErrorAt(where, "empty field (a comma with no value before it)");
    const std::size_t begin = pos;
    while (pos < line.size() && !IsSeparator(line[pos])) ++pos;
    if (fields->count < LineFields::kMaxKept) {
      fields->first[fields->count] = line.substr(begin, pos - begin);
    }
    ++fields->count;
    skip_spaces();
    if (pos < line.size() && line[pos] == ',') {
      ++pos;
      skip_spaces();
      if (pos == line.size()) return ErrorAt(where, "empty field (a comma with no value after it)");
    }
  }
  return absl::OkStatus();
}

// The column count every data line must have: 3 or 6, set by the first data line.
struct ColumnRule {
  std::size_t columns = 0;  // 0 until the first data line
  std::uint64_t line = 0;   // the line that set it

  absl::Status Check(std::size_t count, const Location& where) {
    if (columns == 0) {
      if (count != 3 && count != 6) {
        return ErrorAt(where, absl::StrCat("has ", count,
                                           " fields; expected 3 (x y z) or 6 (x y z nx ny nz)"));
      }
      columns = count;
      line = where.position;
      return absl::OkStatus();
    }
    if (count != columns) {
      return ErrorAt(where, absl::StrCat("has ", count, " fields but line ", line, " has ", columns,
                                         "; every line must have the same count"));
    }
    return absl::OkStatus();
  }
};

}  // namespace

absl::StatusOr<PointCloud> ParseXyz(std::string_view bytes) {
  io_internal::LineCursor lines(bytes);
  PointCloud cloud;
  ColumnRule rule;
  bool before_first_content_line = true;
  LineFields fields;
  io_internal::PointValues values{};
  std::string_view line;
  while (lines.Next(&line)) {
    if (IsBlankOrComment(line)) continue;
    if (std::exchange(before_first_content_line, false) && HasNoNumber(line)) continue;  // Header.
    const Location where = {kXyz, Location::Unit::kLine, lines.line_number(), "point",
                            cloud.size()};
    if (absl::Status s = SplitFields(line, where, &fields); !s.ok()) return s;
    if (absl::Status s = rule.Check(fields.count, where); !s.ok()) return s;
    for (std::size_t k = 0; k < fields.count; ++k) {
      const std::optional<double> value = io_internal::ParseDouble(fields.first[k]);
      if (!value) {
        return ErrorAt(where,
                       absl::StrCat(io_internal::Quote(fields.first[k]), " is not a number"));
      }
      values[k] = *value;
    }
    const bool with_normal = fields.count == 6;
    if (absl::Status s = io_internal::AppendPoint(values, with_normal, where, &cloud); !s.ok()) {
      return s;
    }
  }
  return io_internal::FinishCloud(kXyz, std::move(cloud));
}

std::string SerializeXyz(const PointCloud& cloud) {
  std::string out;
  io_internal::AppendPointsAsText(cloud, &out);
  return out;
}

}  // namespace mlsreg
