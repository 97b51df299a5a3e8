// PCD reader and writer (PCL's Point Cloud Data format, version 0.7). See mlsreg/io.h.
//
// Reading is two steps: collect the header lines ("KEYWORD values...", up to DATA) and check them
// into a PcdHeader (fields with their types, the point count, the viewpoint), then read the points
// in ASCII (one line per point), binary (fixed-size little-endian records) or binary_compressed
// (LZF-compressed fields, lzf.h).

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
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
#include "lzf.h"
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
  bool packed_color = false;  // rgb or rgba: one 32-bit word 0xAARRGGBB (as F, U or I)
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::uint64_t values_per_point = 0;  // ASCII tokens per line
  std::uint64_t record_bytes = 0;      // bytes per point in binary
  bool has_normals = false;
  bool has_colors = false;
  std::vector<std::string> ignored;  // fields read and skipped (padding "_" not counted)
  std::uint64_t points = 0;
  std::optional<Vec3> viewpoint;
  bool compressed = false;  // DATA binary_compressed (encoding kBinary)
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
    if (field.name == "rgb" || field.name == "rgba") {
      if (header->has_colors) {
        return ErrorAt(AtLine(kPcd, raw.fields->line), "FIELDS has both rgb and rgba");
      }
      if (field.count != 1 || field.type.size != 4) {
        return ErrorAt(AtLine(kPcd, raw.type->line),
                       absl::StrCat("field '", field.name, "' must have SIZE 4 and COUNT 1"));
      }
      field.packed_color = header->has_colors = true;
      field.component = Component::kRed;
    } else if (field.component == Component::kNotAComponent && field.name != "_") {
      header->ignored.push_back(field.name);
    }
    if (field.component != Component::kNotAComponent && !field.packed_color) {
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
  if (raw.data->values.size() != 1) {
    return ErrorAt(where, "expected \"DATA ascii|binary|binary_compressed\"");
  }
  if (data == "ascii") {
    header->encoding = PcdEncoding::kAscii;
  } else if (data == "binary") {
    header->encoding = PcdEncoding::kBinary;
  } else if (data == "binary_compressed") {
    header->encoding = PcdEncoding::kBinary;
    header->compressed = true;
  } else {
    return ErrorAt(where, absl::StrCat("unknown DATA encoding ", Quote(data),
                                       " (expected ascii, binary or binary_compressed)"));
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

// Stores the channels of PCL's packed colour word in `values`.
void SetPackedColor(std::uint32_t bits, PointValues* values) {
  const Rgb color = io_internal::UnpackRgb(bits);
  for (int k = 0; k < 3; ++k) (*values)[Component::kRed + k] = color[k];
}

// The packed colour word a text value of `field` stands for: a float's bits (TYPE F, as PCL
// writes rgb), or an integer's.
std::optional<std::uint32_t> PackedColorBits(const PcdField& field, double value) {
  if (field.type.kind == ScalarType::Kind::kFloat) {
    return std::bit_cast<std::uint32_t>(static_cast<float>(value));
  }
  const double min = field.type.kind == ScalarType::Kind::kSigned ? -2147483648.0 : 0.0;
  const double max = field.type.kind == ScalarType::Kind::kSigned ? 2147483647.0 : 4294967295.0;
  if (!(value >= min && value <= max) || value != std::floor(value)) return std::nullopt;
  return static_cast<std::uint32_t>(static_cast<std::int64_t>(value));
}

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
      if (field.packed_color) {
        const std::optional<std::uint32_t> bits = PackedColorBits(field, *value);
        if (!bits) {
          return ErrorAt(where, absl::StrCat("field '", field.name, "': ", Quote(token),
                                             " is not a packed colour"));
        }
        SetPackedColor(*bits, values);
      } else if (field.component != Component::kNotAComponent) {
        (*values)[field.component] = *value;
      }
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
  io_internal::ReservePoints(header.points, max_lines, header.has_normals, cloud,
                             header.has_colors);
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
    if (header.has_colors) cloud->colors.push_back(io_internal::ColorOf(values));
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
  bool packed_color;
};

std::vector<ComponentSlot> ComponentSlots(const PcdHeader& header) {
  std::vector<ComponentSlot> slots;
  std::uint64_t offset = 0;
  for (const PcdField& field : header.fields) {
    if (field.component != Component::kNotAComponent) {
      slots.push_back({field.component, offset, field.type, field.packed_color});
    }
    offset += field.count * field.type.size;
  }
  return slots;
}

std::uint32_t LittleEndianWord(const char* data) {
  std::uint32_t word = 0;
  for (int k = 0; k < 4; ++k) word |= std::uint32_t{static_cast<unsigned char>(data[k])} << (8 * k);
  return word;
}

// Appends the header.points records at `records` (one every header.record_bytes) to `cloud`;
// errors name the file offset first_offset + i * offset_step of point i.
absl::Status DecodeRecords(const PcdHeader& header, const char* records, std::uint64_t first_offset,
                           std::uint64_t offset_step, PointCloud* cloud) {
  io_internal::ReservePoints(header.points, header.points, header.has_normals, cloud,
                             header.has_colors);
  const std::vector<ComponentSlot> slots = ComponentSlots(header);
  PointValues values{};
  for (std::uint64_t i = 0; i < header.points; ++i) {
    const char* record = records + i * header.record_bytes;
    for (const ComponentSlot& slot : slots) {
      if (slot.packed_color) {
        SetPackedColor(LittleEndianWord(record + slot.offset), &values);
      } else {
        values[slot.component] =
            io_internal::DecodeScalar(record + slot.offset, slot.type, std::endian::little);
      }
    }
    const Location where = {kPcd, Location::Unit::kByteOffset, first_offset + i * offset_step,
                            "point", i};
    if (absl::Status s = AppendPoint(values, header.has_normals, where, cloud); !s.ok()) return s;
    if (header.has_colors) cloud->colors.push_back(io_internal::ColorOf(values));
  }
  return absl::OkStatus();
}

// Only blank space may follow the data.
absl::Status CheckNothingAfter(std::string_view bytes, std::uint64_t end) {
  if (io_internal::IsBlank(bytes.substr(end))) return absl::OkStatus();
  return ErrorAt(AtOffset(kPcd, end),
                 absl::StrCat(bytes.size() - end,
                              " unexpected bytes after the last point the header declares"));
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
  if (absl::Status s = DecodeRecords(header, bytes.data() + data_offset, data_offset,
                                     header.record_bytes, cloud);
      !s.ok()) {
    return s;
  }
  return CheckNothingAfter(bytes, data_offset + header.points * header.record_bytes);
}

// The most bytes LZF can produce from one input byte: a 3-byte back reference of 264 bytes.
constexpr std::uint64_t kLzfMaxExpansion = 88;

// DATA binary_compressed (PCL): the compressed and uncompressed sizes (little-endian 32-bit
// words), then the LZF-compressed data, which holds each field of every point in turn (all
// points' x, then all points' y, ...).
absl::Status ReadCompressedPoints(const PcdHeader& header, std::string_view bytes,
                                  std::size_t data_offset, PointCloud* cloud) {
  const Location at = AtOffset(kPcd, data_offset);
  const std::uint64_t available = bytes.size() - data_offset;
  if (available < 8) {
    return ErrorAt(at,
                   "binary_compressed data must start with its compressed and uncompressed "
                   "sizes (8 bytes)");
  }
  const std::uint64_t compressed = LittleEndianWord(bytes.data() + data_offset);
  const std::uint64_t uncompressed = LittleEndianWord(bytes.data() + data_offset + 4);
  if (compressed > available - 8) {
    return ErrorAt(at, absl::StrCat("the compressed data are declared as ", compressed,
                                    " bytes but only ", available - 8, " follow"));
  }
  if (header.points > UINT64_MAX / header.record_bytes ||
      header.points * header.record_bytes != uncompressed) {
    return ErrorAt(at, absl::StrCat("the uncompressed size ", uncompressed, " is not POINTS x ",
                                    header.record_bytes, " bytes per point (",
                                    ByteCount(header.points, header.record_bytes), ")"));
  }
  if (uncompressed / kLzfMaxExpansion > compressed) {
    return ErrorAt(at, absl::StrCat("LZF cannot expand ", compressed, " bytes to ", uncompressed));
  }
  absl::StatusOr<std::string> fields =
      io_internal::LzfDecompress(bytes.substr(data_offset + 8, compressed), uncompressed);
  if (!fields.ok()) return ErrorAt(at, std::string(fields.status().message()));
  // Field by field (structure of arrays) into records, as binary data lays them out.
  std::string records(uncompressed, '\0');
  std::uint64_t field_start = 0, record_offset = 0;
  for (const PcdField& field : header.fields) {
    const std::uint64_t field_bytes = field.count * field.type.size;
    for (std::uint64_t i = 0; i < header.points; ++i) {
      std::memcpy(records.data() + i * header.record_bytes + record_offset,
                  fields->data() + field_start + i * field_bytes, field_bytes);
    }
    field_start += header.points * field_bytes;
    record_offset += field_bytes;
  }
  if (absl::Status s = DecodeRecords(header, records.data(), data_offset, 0, cloud); !s.ok()) {
    return s;
  }
  return CheckNothingAfter(bytes, data_offset + 8 + compressed);
}

// ---------------------------------------------------------------------------------------------
// Writer.

std::string PcdHeaderText(const PointCloud& cloud, PcdEncoding encoding,
                          const io_internal::ScalarFields& scalars) {
  std::vector<std::string> names = {"x", "y", "z"}, sizes(3, "8");
  if (io_internal::WritesNormals(cloud)) {
    names.insert(names.end(), {"normal_x", "normal_y", "normal_z"});
    sizes.insert(sizes.end(), 3, "8");
  }
  for (const auto& [name, values] : scalars) {
    names.push_back(name);
    sizes.push_back("4");
  }
  if (io_internal::WritesColors(cloud)) {
    names.push_back("rgb");
    sizes.push_back("4");
  }
  std::string header =
      absl::StrCat("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS ",
                   absl::StrJoin(names, " "), "\nSIZE ", absl::StrJoin(sizes, " "), "\nTYPE ",
                   absl::StrJoin(std::vector<std::string>(names.size(), "F"), " "), "\nCOUNT ",
                   absl::StrJoin(std::vector<std::string>(names.size(), "1"), " "), "\n");
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

namespace io_internal {

absl::StatusOr<CloudFile> ParsePcdFile(std::string_view bytes) {
  LineCursor lines(bytes);
  absl::StatusOr<PcdHeader> header = ParsePcdHeader(lines);
  if (!header.ok()) return header.status();
  PointCloud cloud;
  cloud.viewpoint = header->viewpoint;
  const absl::Status status =
      header->encoding == PcdEncoding::kAscii ? ReadAsciiPoints(*header, lines, &cloud)
      : header->compressed ? ReadCompressedPoints(*header, bytes, lines.offset(), &cloud)
                           : ReadBinaryPoints(*header, bytes, lines.offset(), &cloud);
  if (!status.ok()) return status;
  absl::StatusOr<PointCloud> finished = FinishCloud(kPcd, std::move(cloud));
  if (!finished.ok()) return finished.status();
  CloudFile file{*std::move(finished), {}};
  if (!header->ignored.empty()) {
    file.notes.push_back(
        absl::StrCat("PCD: fields read and ignored: ", absl::StrJoin(header->ignored, ", ")));
  }
  return file;
}

std::string PcdBytes(const PointCloud& cloud, PcdEncoding encoding, const ScalarFields& scalars) {
  std::string out = PcdHeaderText(cloud, encoding, scalars);
  const RecordLayout layout{.scalars = &scalars, .colors = ColorEncoding::kPackedFloat};
  if (encoding == PcdEncoding::kAscii) {
    AppendRecordsAsText(cloud, layout, ' ', &out);
  } else {
    AppendRecordsAsBinary(cloud, layout, std::endian::little, &out);
  }
  return out;
}

}  // namespace io_internal

absl::StatusOr<PointCloud> ParsePcd(std::string_view bytes) {
  absl::StatusOr<CloudFile> file = io_internal::ParsePcdFile(bytes);
  if (!file.ok()) return file.status();
  return std::move(file->cloud);
}

std::string SerializePcd(const PointCloud& cloud, PcdEncoding encoding) {
  return io_internal::PcdBytes(cloud, encoding, {});
}

}  // namespace mlsreg
