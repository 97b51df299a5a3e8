// XYZ / CSV reader and writer: one point per line, columns named by a header line, the caller or
// their count (table_columns.h). See mlsreg/io.h.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "io_internal.h"
#include "mlsreg/io/io.h"
#include "table_columns.h"

namespace mlsreg {
namespace {

using io_internal::AtLine;
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

// Splits `line` into fields separated by whitespace and/or one comma. A comma with no field before
// or after it (",1,2", "1,,2", "1,2,") is an error: an empty field is a missing value.
absl::Status SplitFields(std::string_view line, const Location& where,
                         std::vector<std::string_view>* fields) {
  fields->clear();
  std::size_t pos = 0;
  const auto skip_spaces = [&] {
    while (pos < line.size() && IsSpace(line[pos])) ++pos;
  };
  skip_spaces();
  while (pos < line.size()) {
    if (line[pos] == ',') return ErrorAt(where, "empty field (a comma with no value before it)");
    const std::size_t begin = pos;
    while (pos < line.size() && !IsSeparator(line[pos])) ++pos;
    fields->push_back(line.substr(begin, pos - begin));
    skip_spaces();
    if (pos < line.size() && line[pos] == ',') {
      ++pos;
      skip_spaces();
      if (pos == line.size()) return ErrorAt(where, "empty field (a comma with no value after it)");
    }
  }
  return absl::OkStatus();
}

// The columns: named by `options`, by the header line, or by the first data line's count.
absl::StatusOr<io_internal::ColumnLayout> LayoutOf(const ReadOptions& options,
                                                   const std::vector<std::string_view>& header,
                                                   std::size_t first_count, const Location& where) {
  if (!options.columns.empty())
    return io_internal::LayoutFromNames(options.columns, "the columns given");
  if (!header.empty()) {
    return io_internal::LayoutFromNames(std::vector<std::string>(header.begin(), header.end()),
                                        "the header line");
  }
  absl::StatusOr<io_internal::ColumnLayout> layout = io_internal::LayoutFromCount(first_count);
  if (!layout.ok()) return ErrorAt(where, std::string(layout.status().message()));
  return layout;
}

}  // namespace

namespace io_internal {

absl::StatusOr<CloudFile> ParseXyzFile(std::string_view bytes, const ReadOptions& options) {
  LineCursor lines(bytes);
  std::optional<TableCloud> table;
  std::vector<std::string_view> header, fields;
  std::uint64_t first_data_line = 0;
  bool before_first_content_line = true;
  std::vector<double> values;
  std::string_view line;
  while (lines.Next(&line)) {
    if (IsBlankOrComment(line)) continue;
    if (std::exchange(before_first_content_line, false) && HasNoNumber(line)) {  // Header.
      if (absl::Status s = SplitFields(line, AtLine(kXyz, lines.line_number()), &header); !s.ok()) {
        return s;
      }
      continue;
    }
    const Location where = {kXyz, Location::Unit::kLine, lines.line_number(), "point",
                            table ? table->size() : 0};
    if (absl::Status s = SplitFields(line, where, &fields); !s.ok()) return s;
    if (!table) {
      absl::StatusOr<ColumnLayout> layout = LayoutOf(options, header, fields.size(), where);
      if (!layout.ok()) return layout.status();
      table.emplace(kXyz, *std::move(layout));
      table->Reserve(MaxTextLines(lines.rest().size() + line.size() + 1, fields.size()));
      first_data_line = lines.line_number();
      values.resize(table->layout().roles.size());
    }
    if (fields.size() != values.size()) {
      return ErrorAt(where, absl::StrCat("has ", fields.size(), " fields but ",
                                         table->layout().origin.empty()
                                             ? absl::StrCat("line ", first_data_line, " has ")
                                             : absl::StrCat(table->layout().origin, " names "),
                                         values.size(), "; every line must have the same count"));
    }
    for (std::size_t k = 0; k < fields.size(); ++k) {
      const std::optional<double> value = ParseDouble(fields[k]);
      if (!value) return ErrorAt(where, absl::StrCat(Quote(fields[k]), " is not a number"));
      values[k] = *value;
    }
    if (absl::Status s = table->AddRow(values.data(), where); !s.ok()) return s;
  }
  if (!table) return absl::InvalidArgumentError("XYZ file contains no points");
  return std::move(*table).Finish();
}

}  // namespace io_internal

absl::StatusOr<PointCloud> ParseXyz(std::string_view bytes) {
  absl::StatusOr<CloudFile> file = io_internal::ParseXyzFile(bytes, {});
  if (!file.ok()) return file.status();
  return std::move(file->cloud);
}

namespace io_internal {

std::string XyzText(const PointCloud& cloud, const ScalarFields& scalars, char separator) {
  std::vector<std::string> names = {"x", "y", "z"};
  if (WritesNormals(cloud)) names.insert(names.end(), {"nx", "ny", "nz"});
  for (const auto& [name, values] : scalars) names.push_back(name);
  if (WritesColors(cloud)) names.insert(names.end(), {"r", "g", "b"});
  std::string out;
  if (names.size() > 3) out = absl::StrCat(absl::StrJoin(names, std::string(1, separator)), "\n");
  AppendRecordsAsText(cloud, {.scalars = &scalars}, separator, &out);
  return out;
}

}  // namespace io_internal

std::string SerializeXyz(const PointCloud& cloud) { return io_internal::XyzText(cloud, {}, ' '); }

}  // namespace mlsreg
