// PCD reader and writer (PCL's Point Cloud Data format, version 0.7). See mlsreg/io.h.
//
// Reading is two steps: collect the header lines ("KEYWORD values...", up to DATA) and check them
// into a PcdHeader (fields with their types, the point count, the viewpoint), then read the points
// in ASCII (one line per point) or binary (fixed-size little-endian records).

#include <bit>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "io_internal.h"
#include "mlsreg/io/io.h"

namespace mlsreg {
namespace {

using io_internal::AppendPoint;
using io_internal::AtLine;
using io_internal::AtOffset;
using io_internal::ByteCount;
using io_internal::Component;
using io_internal::ErrorAt;
using io_internal::LineCursor;
using io_internal::Location;
using io_internal::NextToken;
using io_internal::PointValues;
using io_internal::Quote;
using io_internal::ScalarType;
using io_internal::ToAbsl;

constexpr std::string_view kPcd = "PCD";

// ---------------------------------------------------------------------------------------------
// Header lines as found, before they are checked.

struct PcdHeaderEntry {
  std::uint64_t line = 0;
  std::vector<std::string_view> values;
};

struct RawPcdHeader {
  std::optional<PcdHeaderEntry> version, fields, size, type, count, width, height, viewpoint,
      points, data;
};

std::optional<PcdHeaderEntry>* FindEntry(RawPcdHeader& raw, std::string_view keyword) {
  if (keyword == "VERSION") return &raw.version;
  if (keyword == "FIELDS") return &raw.fields;
  if (keyword == "SIZE") return &raw.size;
  if (keyword == "TYPE") return &raw.type;
  if (keyword == "COUNT") return &raw.count;
  if (keyword == "WIDTH") return &raw.width;
  if (keyword == "HEIGHT") return &raw.height;
  if (keyword == "VIEWPOINT") return &raw.viewpoint;
  if (keyword == "POINTS") return &raw.points;
  if (keyword == "DATA") return &raw.data;
  return nullptr;
}

// Reads header lines up to and including DATA, skipping blank lines and '#' comments.
absl::StatusOr<RawPcdHeader> ReadRawPcdHeader(LineCursor& lines) {
  RawPcdHeader raw;
  std::string_view line;
  while (!raw.data) {
    if (!lines.Next(&line)) return absl::InvalidArgumentError("PCD header has no DATA line");
    std::string_view keyword;
    if (!NextToken(&line, &keyword) || keyword[0] == '#') continue;
    const Location where = AtLine(kPcd, lines.line_number());
    std::optional<PcdHeaderEntry>* entry = FindEntry(raw, keyword);
    if (entry == nullptr) {
      return ErrorAt(where, absl::StrCat("unknown header keyword ", Quote(keyword)));
    }
    if (entry->has_value()) {
      return ErrorAt(where, absl::StrCat("second ", ToAbsl(keyword), " line"));
    }
    PcdHeaderEntry found;
    found.line = lines.line_number();
    for (std::string_view value; NextToken(&line, &value);) found.values.push_back(value);
    if (found.values.empty()) return ErrorAt(where, absl::StrCat(ToAbsl(keyword), " has no value"));
    *entry = std::move(found);
  }
  return raw;
}

// ---------------------------------------------------------------------------------------------
// The checked header.

struct PcdField {
  std::string name;
  ScalarType type{};
  std::uint64_t count = 1;  // values of this field per point
  int component = Component::kNotAComponent;
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t values_per_point = 0;  // ASCII tokens per line
  std::uint64_t record_bytes = 0;      // bytes per point in binary
  bool has_normals = false;
  std::uint64_t points = 0;
  std::optional<Vec3> viewpoint;
  PcdEncoding encoding = PcdEncoding::kAscii;
};

absl::Status CheckVersion(const RawPcdHeader& raw) {
  if (!raw.version) return absl::OkStatus();
  const std::string_view version = raw.version->values[0];
  if (version == "0.7" || version == ".7" || version == "0.6" || version == ".6") {
    return absl::OkStatus();
  }
  return absl::UnimplementedError(absl::StrCat(ToString(AtLine(kPcd, raw.version->line)),
                                               ": PCD version ", Quote(version),
                                               " is not supported (0.7 and 0.6 are)"));
}

// The type of a field from its TYPE and SIZE entries: F 4|8, I or U 1|2|4|8.
std::optional<ScalarType> ParsePcdType(std::string_view type, std::string_view size) {
  const std::optional<std::uint64_t> bytes = io_internal::ParseUint64(size);
  if (!bytes || type.size() != 1) return std::nullopt;
  const bool valid_integer_size = *bytes == 1 || *bytes == 2 || *bytes == 4 || *bytes == 8;
  const auto size8 = static_cast<std::uint8_t>(*bytes);
  switch (type[0]) {
    case 'F':
      if (*bytes != 4 && *bytes != 8) return std::nullopt;
      return ScalarType{ScalarType::Kind::kFloat, size8};
    case 'I':
      if (!valid_integer_size) return std::nullopt;
      return ScalarType{ScalarType::Kind::kSigned, size8};
    case 'U':
      if (!valid_integer_size) return std::nullopt;
      return ScalarType{ScalarType::Kind::kUnsigned, size8};
    default:
      return std::nullopt;
  }
}

int ComponentOfField(std::string_view name) {
  static constexpr std::string_view kNames[] = {"x", "y", "z", "normal_x", "normal_y", "normal_z"};
  for (int component = 0; component < 6; ++component) {
    if (name == kNames[component]) return component;
  }
  return Component::kNotAComponent;
}

// Checks that SIZE, TYPE and COUNT (when present) have one value per entry of FIELDS.
absl::Status CheckFieldListLengths(const RawPcdHeader& raw) {
  if (!raw.fields) return absl::InvalidArgumentError("PCD header has no FIELDS line");
  if (!raw.size) return absl::InvalidArgumentError("PCD header has no SIZE line");
  if (!raw.type) return absl::InvalidArgumentError("PCD header has no TYPE line");
  const std::size_t n = raw.fields->values.size();
  const std::pair<const char*, const std::optional<PcdHeaderEntry>*> lists[] = {
      {"SIZE", &raw.size}, {"TYPE", &raw.type}, {"COUNT", &raw.count}};
  for (const auto& [keyword, entry] : lists) {
    if (entry->has_value() && (*entry)->values.size() != n) {
      return ErrorAt(
          AtLine(kPcd, (*entry)->line),
          absl::StrCat(keyword, " has ", (*entry)->values.size(), " values but FIELDS has ", n));
    }
  }
  return absl::OkStatus();
}

// Builds header->fields, values_per_point, record_bytes and has_normals from FIELDS, SIZE, TYPE
// and COUNT. x, y, z are required; normal_x, normal_y, normal_z are all there or none is.
absl::Status BuildFields(const RawPcdHeader& raw, PcdHeader* header) {
  if (absl::Status status = CheckFieldListLengths(raw); !status.ok()) return status;
  bool found[6] = {};
  for (std::size_t i = 0; i < raw.fields->values.size(); ++i) {
    PcdField field;
    field.name = std::string(raw.fields->values[i]);
    const std::optional<ScalarType> type = ParsePcdType(raw.type->values[i], raw.size->values[i]);
    if (!type) {
      return ErrorAt(AtLine(kPcd, raw.type->line),
                     absl::StrCat("field '", field.name, "' has TYPE ", Quote(raw.type->values[i]),
                                  " and SIZE ", Quote(raw.size->values[i]),
                                  "; supported are F with SIZE 4 or 8, I or U with 1, 2, 4 or 8"));
    }
    field.type = *type;
    if (raw.count) {
      const std::optional<std::uint64_t> count = io_internal::ParseUint64(raw.count->values[i]);
      if (!count) {
        return ErrorAt(AtLine(kPcd, raw.count->line),
                       absl::StrCat("field '", field.name, "' has an invalid COUNT ",
                                    Quote(raw.count->values[i])));
      }
      field.count = *count;
    }
    field.component = ComponentOfField(field.name);
    if (field.component != Component::kNotAComponent) {
      if (found[field.component]) {
        return ErrorAt(AtLine(kPcd, raw.fields->line),
                       absl::StrCat("field '", field.name, "' appears twice"));
      }
      if (field.count != 1) {
        return ErrorAt(AtLine(kPcd, raw.count->line),
                       absl::StrCat("field '", field.name, "' must have COUNT 1"));
      }
      found[field.component] = true;
    }
    if (field.count > (UINT64_MAX - header->record_bytes) / field.type.size) {
      return ErrorAt(AtLine(kPcd, raw.count ? raw.count->line : raw.fields->line),
                     absl::StrCat("field '", field.name, "' has an absurd COUNT ", field.count));
    }
    header->record_bytes += field.count * field.type.size;
    header->values_per_point += field.count;
    header->fields.push_back(std::move(field));
  }
  for (int axis = 0; axis < 3; ++axis) {
    if (!found[axis]) {
      return ErrorAt(AtLine(kPcd, raw.fields->line),
                     absl::StrCat("FIELDS has no '", ToAbsl(io_internal::kAxisNames[axis]), "'"));
    }
  }
  header->has_normals = found[3] && found[4] && found[5];
  if (!header->has_normals && (found[3] || found[4] || found[5])) {
    return ErrorAt(AtLine(kPcd, raw.fields->line),
                   "FIELDS has only some of normal_x, normal_y, normal_z (all three or none)");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::uint64_t> ParseCountEntry(const std::optional<PcdHeaderEntry>& entry,
                                              std::string_view keyword) {
  const std::optional<std::uint64_t> value = io_internal::ParseUint64(entry->values[0]);
  if (!value || entry->values.size() != 1) {
    return ErrorAt(AtLine(kPcd, entry->line),
                   absl::StrCat(ToAbsl(keyword), " must be one non-negative integer"));
  }
  return *value;
}

// The number of points: POINTS, which must equal WIDTH * HEIGHT when WIDTH is given (HEIGHT
// defaults to 1); WIDTH * HEIGHT when POINTS is missing.
absl::Status BuildPointCount(const RawPcdHeader& raw, PcdHeader* header) {
  std::optional<std::uint64_t> width_times_height;
  if (raw.width) {
    const absl::StatusOr<std::uint64_t> width = ParseCountEntry(raw.width, "WIDTH");
    if (!width.ok()) return width.status();
    std::uint64_t height = 1;
    if (raw.height) {
      const absl::StatusOr<std::uint64_t> parsed = ParseCountEntry(raw.height, "HEIGHT");
      if (!parsed.ok()) return parsed.status();
      height = *parsed;
    }
    if (height != 0 && *width > UINT64_MAX / height) {
      return ErrorAt(AtLine(kPcd, raw.width->line), "WIDTH * HEIGHT does not fit in 64 bits");
    }
    width_times_height = *width * height;
  }
  if (!raw.points) {
    if (!width_times_height) {
      return absl::InvalidArgumentError("PCD header has neither POINTS nor WIDTH");
    }
    header->points = *width_times_height;
    return absl::OkStatus();
  }
  const absl::StatusOr<std::uint64_t> points = ParseCountEntry(raw.points, "POINTS");
  if (!points.ok()) return points.status();
  if (width_times_height && *width_times_height != *points) {
    return ErrorAt(
        AtLine(kPcd, raw.points->line),
        absl::StrCat("POINTS is ", *points, " but WIDTH * HEIGHT is ", *width_times_height));
  }
  header->points = *points;
  return absl::OkStatus();
}

// VIEWPOINT tx ty tz qw qx qy qz: the translation is the sensor origin; the orientation is only
// checked to be numbers.
absl::Status BuildViewpoint(const RawPcdHeader& raw, PcdHeader* header) {
  if (!raw.viewpoint) return absl::OkStatus();
  const Location where = AtLine(kPcd, raw.viewpoint->line);
  if (raw.viewpoint->values.size() != 7) {
    return ErrorAt(where, "VIEWPOINT must have 7 numbers: tx ty tz qw qx qy qz");
  }
  double numbers[7];
  for (int i = 0; i < 7; ++i) {
    const std::optional<double> value = io_internal::ParseDouble(raw.viewpoint->values[i]);
    if (!value || !std::isfinite(*value)) {
      return ErrorAt(where, absl::StrCat("VIEWPOINT value ", Quote(raw.viewpoint->values[i]),
                                         " is not a finite number"));
    }
    numbers[i] = *value;
  }
  header->viewpoint = Vec3(numbers[0], numbers[1], numbers[2]);
  return absl::OkStatus();
}

absl::Status BuildEncoding(const RawPcdHeader& raw, PcdHeader* header) {
  const Location where = AtLine(kPcd, raw.data->line);
  const std::string_view data = raw.data->values[0];
  if (raw.data->values.size() != 1) return ErrorAt(where, "expected \"DATA ascii|binary\"");
  if (data == "ascii") {
    header->encoding = PcdEncoding::kAscii;
  } else if (data == "binary") {
    header->encoding = PcdEncoding::kBinary;
  } else if (data == "binary_compressed") {
    return absl::UnimplementedError(
        absl::StrCat(ToString(where),
                     ": DATA binary_compressed is not supported; convert the file "
                     "to binary or ascii (e.g. with PCL's pcl_convert_pcd_ascii_binary)"));
  } else {
    return ErrorAt(
        where, absl::StrCat("unknown DATA encoding ", Quote(data), " (expected ascii or binary)"));
  }
  return absl::OkStatus();
}

// Parses the header, leaving `lines` just after the DATA line.
absl::StatusOr<PcdHeader> ParsePcdHeader(LineCursor& lines) {
  absl::StatusOr<RawPcdHeader> raw = ReadRawPcdHeader(lines);
  if (!raw.ok()) return raw.status();
  if (absl::Status status = CheckVersion(*raw); !status.ok()) return status;
  PcdHeader header;
  if (absl::Status status = BuildFields(*raw, &header); !status.ok()) return status;
  if (absl::Status status = BuildPointCount(*raw, &header); !status.ok()) return status;
  if (absl::Status status = BuildViewpoint(*raw, &header); !status.ok()) return status;
  if (absl::Status status = BuildEncoding(*raw, &header); !status.ok()) return status;
  return header;
}

// ---------------------------------------------------------------------------------------------
// ASCII data: one point per line.

absl::Status ReadAsciiPoint(const PcdHeader& header, std::string_view line, const Location& where,
                            PointValues* values) {
  std::string_view token;
  for (const PcdField& field : header.fields) {
    for (std::uint64_t k = 0; k < field.count; ++k) {
      if (!NextToken(&line, &token)) {
        return ErrorAt(where, absl::StrCat("the line ends before field '", field.name, "'"));
      }
      const std::optional<double> value = io_internal::ParseDouble(token);
      if (!value) {
        return ErrorAt(
            where, absl::StrCat("field '", field.name, "': ", Quote(token), " is not a number"));
      }
      if (field.component != Component::kNotAComponent) (*values)[field.component] = *value;
    }
  }
  if (NextToken(&line, &token)) {
    return ErrorAt(where, absl::StrCat("unexpected ", Quote(token), " after the last field"));
  }
  return absl::OkStatus();
}

absl::Status ReadAsciiPoints(const PcdHeader& header, LineCursor& lines, PointCloud* cloud) {
  const std::uint64_t max_lines =
      io_internal::MaxTextLines(lines.rest().size(), header.values_per_point);
  io_internal::ReservePoints(header.points, max_lines, header.has_normals, cloud);
  std::string_view line;
  PointValues values{};
  for (std::uint64_t i = 0; i < header.points; ++i) {
    if (!lines.Next(&line)) {
      return ErrorAt(AtLine(kPcd, lines.line_number()),
                     absl::StrCat("the file ends after ", i, " of the ", header.points,
                                  " points the header declares"));
    }
    const Location where = {kPcd, Location::Unit::kLine, lines.line_number(), "point", i};
    if (absl::Status s = ReadAsciiPoint(header, line, where, &values); !s.ok()) return s;
    if (absl::Status s = AppendPoint(values, header.has_normals, where, cloud); !s.ok()) return s;
  }
  while (lines.Next(&line)) {
    if (!io_internal::IsBlank(line)) {
      return ErrorAt(AtLine(kPcd, lines.line_number()),
                     "unexpected data after the last point the header declares");
    }
  }
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------------------------
// Binary data: fixed-size little-endian records, fields in FIELDS order.

// Where, inside a point record, a field holding a point component is.
struct ComponentSlot {
  int component;
  std::uint64_t offset;
  ScalarType type;
};

std::vector<ComponentSlot> ComponentSlots(const PcdHeader& header) {
  std::vector<ComponentSlot> slots;
  std::uint64_t offset = 0;
  for (const PcdField& field : header.fields) {
    if (field.component != Component::kNotAComponent) {
      slots.push_back({field.component, offset, field.type});
    }
    offset += field.count * field.type.size;
  }
  return slots;
}

absl::Status ReadBinaryPoints(const PcdHeader& header, std::string_view bytes,
                              std::size_t data_offset, PointCloud* cloud) {
  const std::uint64_t available = bytes.size() - data_offset;
  if (header.points > available / header.record_bytes) {
    return ErrorAt(AtOffset(kPcd, data_offset),
                   absl::StrCat("header declares ", header.points, " points (",
                                ByteCount(header.points, header.record_bytes), ") but only ",
                                available, " bytes follow the header"));
  }
  io_internal::ReservePoints(header.points, header.points, header.has_normals, cloud);
  const std::vector<ComponentSlot> slots = ComponentSlots(header);
  PointValues values{};
  for (std::uint64_t i = 0; i < header.points; ++i) {
    const std::uint64_t record = data_offset + i * header.record_bytes;
    for (const ComponentSlot& slot : slots) {
      values[slot.component] = io_internal::DecodeScalar(bytes.data() + record + slot.offset,
                                                         slot.type, std::endian::little);
    }
    const Location where = {kPcd, Location::Unit::kByteOffset, record, "point", i};
    if (absl::Status s = AppendPoint(values, header.has_normals, where, cloud); !s.ok()) return s;
  }
  const std::uint64_t end = data_offset + header.points * header.record_bytes;
  if (!io_internal::IsBlank(bytes.substr(end))) {
    return ErrorAt(AtOffset(kPcd, end),
                   absl::StrCat(bytes.size() - end,
                                " unexpected bytes after the last point the header declares"));
  }
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------------------------
// Writer.

std::string PcdHeaderText(const PointCloud& cloud, PcdEncoding encoding) {
  std::string header = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n";
  header += io_internal::WritesNormals(cloud)
                ? "FIELDS x y z normal_x normal_y normal_z\nSIZE 8 8 8 8 8 8\n"
                  "TYPE F F F F F F\nCOUNT 1 1 1 1 1 1\n"
                : "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nCOUNT 1 1 1\n";
  absl::StrAppend(&header, "WIDTH ", cloud.size(), "\nHEIGHT 1\nVIEWPOINT");
  const Vec3 origin = cloud.viewpoint.value_or(Vec3::Zero());
  for (int k = 0; k < 3; ++k) {
    header += ' ';
    io_internal::AppendDoubleText(origin[k], &header);
  }
  absl::StrAppend(&header, " 1 0 0 0\nPOINTS ", cloud.size(), "\nDATA ",
                  encoding == PcdEncoding::kAscii ? "ascii" : "binary", "\n");
  return header;
}

}  // namespace

absl::StatusOr<PointCloud> ParsePcd(std::string_view bytes) {
  LineCursor lines(bytes);
  absl::StatusOr<PcdHeader> header = ParsePcdHeader(lines);
  if (!header.ok()) return header.status();
  PointCloud cloud;
  cloud.viewpoint = header->viewpoint;
  const absl::Status status = header->encoding == PcdEncoding::kAscii
                                  ? ReadAsciiPoints(*header, lines, &cloud)
                                  : ReadBinaryPoints(*header, bytes, lines.offset(), &cloud);
  if (!status.ok()) return status;
  return io_internal::FinishCloud(kPcd, std::move(cloud));
}

std::string SerializePcd(const PointCloud& cloud, PcdEncoding encoding) {
  std::string out = PcdHeaderText(cloud, encoding);
  if (encoding == PcdEncoding::kAscii) {
    io_internal::AppendPointsAsText(cloud, &out);
  } else {
    io_internal::AppendPointsAsBinary(cloud, std::endian::little, &out);
  }
  return out;
}

}  // namespace mlsreg
