// PLY reader and writer. See mlsreg/io.h for what is accepted.
//
// Reading is two steps: parse the header into a list of elements (name, count, properties), then
// walk the data of every element in header order, in ASCII or binary. Only the "vertex" element is
// kept; the others are checked (so a truncated or lying file is caught wherever it lies) and
// skipped.

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
#include "absl/strings/str_join.h"
#include "io_internal.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/mesh_io.h"

namespace mlsreg {
namespace {

using io_internal::AppendPoint;
using io_internal::AtLine;
using io_internal::AtOffset;
using io_internal::ByteCount;
using io_internal::Component;
using io_internal::DecodeScalar;
using io_internal::ErrorAt;
using io_internal::LineCursor;
using io_internal::Location;
using io_internal::NextToken;
using io_internal::PointValues;
using io_internal::Quote;
using io_internal::ScalarType;
using io_internal::ToAbsl;

constexpr std::string_view kPly = "PLY";
constexpr std::string_view kVertex = "vertex";

// ---------------------------------------------------------------------------------------------
// Header.

struct PlyProperty {
  std::string name;
  ScalarType type{};                          // of the value, or of each item of a list
  std::optional<ScalarType> list_count_type;  // set for "property list <count> <item> <name>"
  int component = Component::kNotAComponent;  // which point value it holds (vertex element only)
  double scale = 1.0;  // a colour channel: from the type's range (or [0, 1] for floats) to 0-255
  bool face_indices = false;  // the face element's vertex_indices list, kept when reading a mesh
};

// The polygons of a mesh as read: sizes[i] vertex indices per polygon, all in one array.
struct PlyPolygons {
  std::vector<std::uint32_t> sizes;
  std::vector<double> indices;
};

// Keeps one list item when `property` holds face vertex indices and polygons are being read.
void KeepListItem(const PlyProperty& property, double value, PlyPolygons* polygons) {
  if (polygons != nullptr && property.face_indices) polygons->indices.push_back(value);
}
void KeepListSize(const PlyProperty& property, std::uint64_t count, PlyPolygons* polygons) {
  if (polygons != nullptr && property.face_indices) {
    polygons->sizes.push_back(static_cast<std::uint32_t>(count));
  }
}

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
  std::uint64_t header_line = 0;
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;  // in file order
  bool has_normals = false;          // the vertex element has nx, ny, nz
  bool has_colors = false;           // the vertex element has red, green, blue
  std::vector<std::string> ignored;  // the vertex element's other properties
};

// The factor from a colour property's values to 0-255: floats are in [0, 1], integers span
// their type's range.
double ColorScale(ScalarType type) {
  if (type.kind == ScalarType::Kind::kFloat) return 255.0;
  const int bits = 8 * type.size - (type.kind == ScalarType::Kind::kSigned ? 1 : 0);
  return 255.0 / (std::ldexp(1.0, bits) - 1.0);
}

std::optional<ScalarType> ParsePlyType(std::string_view name) {
  using Kind = ScalarType::Kind;
  struct NamedType {
    std::string_view name;
    ScalarType type;
  };
  static constexpr NamedType kTypes[] = {
      {"char", {Kind::kSigned, 1}},     {"int8", {Kind::kSigned, 1}},
      {"uchar", {Kind::kUnsigned, 1}},  {"uint8", {Kind::kUnsigned, 1}},
      {"short", {Kind::kSigned, 2}},    {"int16", {Kind::kSigned, 2}},
      {"ushort", {Kind::kUnsigned, 2}}, {"uint16", {Kind::kUnsigned, 2}},
      {"int", {Kind::kSigned, 4}},      {"int32", {Kind::kSigned, 4}},
      {"uint", {Kind::kUnsigned, 4}},   {"uint32", {Kind::kUnsigned, 4}},
      {"float", {Kind::kFloat, 4}},     {"float32", {Kind::kFloat, 4}},
      {"double", {Kind::kFloat, 8}},    {"float64", {Kind::kFloat, 8}},
  };
  for (const NamedType& entry : kTypes) {
    if (entry.name == name) return entry.type;
  }
  return std::nullopt;
}

// Splits the rest of a header line into exactly `expected` tokens.
absl::Status SplitHeaderLine(std::string_view rest, std::size_t expected, std::string_view usage,
                             const Location& where, std::vector<std::string_view>* tokens) {
  tokens->clear();
  std::string_view token;
  while (NextToken(&rest, &token)) tokens->push_back(token);
  if (tokens->size() != expected) {
    return ErrorAt(where, absl::StrCat("expected \"", ToAbsl(usage), "\""));
  }
  return absl::OkStatus();
}

absl::Status ParseFormatLine(std::string_view rest, const Location& where, bool* seen_format,
                             PlyHeader* header) {
  std::vector<std::string_view> tokens;
  if (absl::Status s = SplitHeaderLine(rest, 2, "format <encoding> 1.0", where, &tokens); !s.ok()) {
    return s;
  }
  if (*seen_format) return ErrorAt(where, "second \"format\" line");
  *seen_format = true;
  if (tokens[0] == "ascii") {
    header->encoding = PlyEncoding::kAscii;
  } else if (tokens[0] == "binary_little_endian") {
    header->encoding = PlyEncoding::kBinaryLittleEndian;
  } else if (tokens[0] == "binary_big_endian") {
    header->encoding = PlyEncoding::kBinaryBigEndian;
  } else {
    return ErrorAt(where, absl::StrCat("unknown format ", Quote(tokens[0]),
                                       " (expected ascii, binary_little_endian or "
                                       "binary_big_endian)"));
  }
  if (tokens[1] != "1.0") {
    return ErrorAt(
        where, absl::StrCat("unsupported PLY version ", Quote(tokens[1]), " (only 1.0 exists)"));
  }
  return absl::OkStatus();
}

absl::Status ParseElementLine(std::string_view rest, const Location& where, PlyHeader* header) {
  std::vector<std::string_view> tokens;
  if (absl::Status s = SplitHeaderLine(rest, 2, "element <name> <count>", where, &tokens);
      !s.ok()) {
    return s;
  }
  const std::optional<std::uint64_t> count = io_internal::ParseUint64(tokens[1]);
  if (!count) {
    return ErrorAt(
        where, absl::StrCat("element count ", Quote(tokens[1]), " is not a non-negative integer"));
  }
  if (tokens[0] == kVertex) {
    for (const PlyElement& element : header->elements) {
      if (element.name == kVertex) return ErrorAt(where, "second \"vertex\" element");
    }
  }
  PlyElement element;
  element.name = std::string(tokens[0]);
  element.count = *count;
  element.header_line = where.position;
  header->elements.push_back(std::move(element));
  return absl::OkStatus();
}

absl::Status ParsePropertyLine(std::string_view rest, const Location& where, PlyHeader* header) {
  if (header->elements.empty()) return ErrorAt(where, "\"property\" before any \"element\"");
  std::vector<std::string_view> tokens;
  std::string_view token;
  for (std::string_view r = rest; NextToken(&r, &token);) tokens.push_back(token);
  const bool is_list = !tokens.empty() && tokens[0] == "list";
  if (tokens.size() != (is_list ? 4u : 2u)) {
    return ErrorAt(where,
                   "expected \"property <type> <name>\" or "
                   "\"property list <count type> <item type> <name>\"");
  }
  PlyProperty property;
  property.name = std::string(tokens.back());
  const std::string_view type_name = tokens[is_list ? 2 : 0];
  const std::optional<ScalarType> type = ParsePlyType(type_name);
  if (!type) return ErrorAt(where, absl::StrCat("unknown property type ", Quote(type_name)));
  property.type = *type;
  if (is_list) {
    property.list_count_type = ParsePlyType(tokens[1]);
    if (!property.list_count_type || property.list_count_type->kind == ScalarType::Kind::kFloat) {
      return ErrorAt(
          where, absl::StrCat("list count type ", Quote(tokens[1]), " is not an integer PLY type"));
    }
  }
  PlyElement& element = header->elements.back();
  for (const PlyProperty& existing : element.properties) {
    if (existing.name == property.name) {
      return ErrorAt(where, absl::StrCat("element '", element.name, "' has a second property '",
                                         property.name, "'"));
    }
  }
  element.properties.push_back(std::move(property));
  return absl::OkStatus();
}

// Marks which vertex properties hold x, y, z (required), nx, ny, nz (all three or none) and
// red, green, blue (all three, or they are ignored), and lists the others.
absl::Status AssignVertexComponents(PlyHeader* header) {
  PlyElement* vertex = nullptr;
  for (PlyElement& element : header->elements) {
    if (element.name == kVertex) vertex = &element;
  }
  if (vertex == nullptr) return absl::InvalidArgumentError("PLY header has no \"vertex\" element");
  static constexpr std::string_view kNames[] = {"x",  "y",   "z",     "nx",  "ny",
                                                "nz", "red", "green", "blue"};
  bool found[9] = {};
  for (PlyProperty& property : vertex->properties) {
    for (int component = 0; component < 9; ++component) {
      if (property.name != kNames[component]) continue;
      if (property.list_count_type) {
        return ErrorAt(AtLine(kPly, vertex->header_line),
                       absl::StrCat("vertex property '", property.name,
                                    "' is a list; it must be a single number"));
      }
      property.component = component;
      if (component >= Component::kRed) property.scale = ColorScale(property.type);
      found[component] = true;
    }
  }
  for (int component = 0; component < 3; ++component) {
    if (!found[component]) {
      return ErrorAt(
          AtLine(kPly, vertex->header_line),
          absl::StrCat("the vertex element has no '", ToAbsl(kNames[component]), "' property"));
    }
  }
  header->has_normals = found[3] && found[4] && found[5];
  if (!header->has_normals && (found[3] || found[4] || found[5])) {
    return ErrorAt(AtLine(kPly, vertex->header_line),
                   "the vertex element has only some of nx, ny, nz (all three or none)");
  }
  header->has_colors = found[6] && found[7] && found[8];
  for (PlyProperty& property : vertex->properties) {
    // Some colour channels only are not a colour: read and ignored, as other properties are.
    if (!header->has_colors && property.component >= Component::kRed) {
      property.component = Component::kNotAComponent;
    }
    if (property.component == Component::kNotAComponent) header->ignored.push_back(property.name);
  }
  return absl::OkStatus();
}

// Parses the header lines, leaving `lines` just after "end_header".
absl::StatusOr<PlyHeader> ParsePlyHeader(LineCursor& lines) {
  std::string_view line;
  std::string_view magic;
  if (!lines.Next(&line) || !NextToken(&line, &magic) || magic != "ply" ||
      !io_internal::IsBlank(line)) {
    return absl::InvalidArgumentError("not a PLY file: the first line must be \"ply\"");
  }
  PlyHeader header;
  bool seen_format = false;
  while (true) {
    if (!lines.Next(&line)) {
      return absl::InvalidArgumentError("PLY header has no \"end_header\" line");
    }
    const Location where = AtLine(kPly, lines.line_number());
    std::string_view keyword;
    if (!NextToken(&line, &keyword)) continue;  // A blank line.
    if (keyword == "end_header") break;
    if (keyword == "comment" || keyword == "obj_info") continue;
    absl::Status status;
    if (keyword == "format") {
      status = ParseFormatLine(line, where, &seen_format, &header);
    } else if (keyword == "element") {
      status = ParseElementLine(line, where, &header);
    } else if (keyword == "property") {
      status = ParsePropertyLine(line, where, &header);
    } else {
      status = ErrorAt(where, absl::StrCat("unknown header keyword ", Quote(keyword)));
    }
    if (!status.ok()) return status;
  }
  if (!seen_format) return absl::InvalidArgumentError("PLY header has no \"format\" line");
  if (absl::Status status = AssignVertexComponents(&header); !status.ok()) return status;
  return header;
}

// ---------------------------------------------------------------------------------------------
// Data, shared by ASCII and binary.

// How messages name the instances of `element`: "vertices" or "'face' elements".
std::string PluralName(const PlyElement& element) {
  if (element.name == kVertex) return "vertices";
  return absl::StrCat("'", element.name, "' elements");
}

// ---------------------------------------------------------------------------------------------
// ASCII data: one element instance per line.

// The maximum a list count of `type` can hold (count types are integers of at most 4 bytes).
std::uint64_t MaxListCount(ScalarType type) {
  const std::uint64_t bits = 8u * type.size - (type.kind == ScalarType::Kind::kSigned ? 1u : 0u);
  return (std::uint64_t{1} << bits) - 1;
}

// Reads the values of one instance of `element` from `line`; vertex values go to `*values`.
absl::Status ReadAsciiInstance(const PlyElement& element, std::string_view line,
                               const Location& where, PointValues* values, PlyPolygons* polygons) {
  std::string_view token;
  for (const PlyProperty& property : element.properties) {
    if (!NextToken(&line, &token)) {
      return ErrorAt(where, absl::StrCat("the line ends before property '", property.name, "'"));
    }
    std::uint64_t items = 1;
    if (property.list_count_type) {
      const std::optional<std::uint64_t> count = io_internal::ParseUint64(token);
      if (!count || *count > MaxListCount(*property.list_count_type)) {
        return ErrorAt(
            where, absl::StrCat("list '", property.name, "' has an invalid count ", Quote(token)));
      }
      items = *count;
      KeepListSize(property, items, polygons);
    }
    for (std::uint64_t item = 0; item < items; ++item) {
      if (property.list_count_type && !NextToken(&line, &token)) {
        return ErrorAt(where, absl::StrCat("list '", property.name, "' has ", items,
                                           " items but the line ends after ", item));
      }
      const std::optional<double> value = io_internal::ParseDouble(token);
      if (!value) {
        return ErrorAt(where, absl::StrCat("property '", property.name, "': ", Quote(token),
                                           " is not a number"));
      }
      if (property.component != Component::kNotAComponent) {
        (*values)[property.component] = *value * property.scale;
      }
      if (property.list_count_type) KeepListItem(property, *value, polygons);
    }
  }
  if (NextToken(&line, &token)) {
    return ErrorAt(where, absl::StrCat("unexpected ", Quote(token), " after the last property"));
  }
  return absl::OkStatus();
}

// Reads every instance of `element`; when `cloud` is set (the vertex element) appends the points.
absl::Status ReadAsciiElement(const PlyElement& element, const PlyHeader& header, LineCursor& lines,
                              PointCloud* cloud, PlyPolygons* polygons) {
  if (cloud != nullptr) {
    const std::uint64_t max_lines =
        io_internal::MaxTextLines(lines.rest().size(), element.properties.size());
    io_internal::ReservePoints(element.count, max_lines, header.has_normals, cloud,
                               header.has_colors);
  }
  std::string_view line;
  PointValues values{};
  for (std::uint64_t i = 0; i < element.count; ++i) {
    if (!lines.Next(&line)) {
      return ErrorAt(AtLine(kPly, lines.line_number()),
                     absl::StrCat("the file ends after ", i, " of the ", element.count, " ",
                                  PluralName(element), " the header declares"));
    }
    const Location where = {kPly, Location::Unit::kLine, lines.line_number(), element.name, i};
    if (absl::Status s = ReadAsciiInstance(element, line, where, &values, polygons); !s.ok()) {
      return s;
    }
    if (cloud != nullptr) {
      if (absl::Status s = AppendPoint(values, header.has_normals, where, cloud); !s.ok()) return s;
      if (header.has_colors) cloud->colors.push_back(io_internal::ColorOf(values));
    }
  }
  return absl::OkStatus();
}

absl::Status ReadAsciiBody(const PlyHeader& header, LineCursor& lines, PointCloud* cloud,
                           PlyPolygons* polygons) {
  for (const PlyElement& element : header.elements) {
    PointCloud* destination = element.name == kVertex ? cloud : nullptr;
    if (absl::Status s = ReadAsciiElement(element, header, lines, destination, polygons); !s.ok()) {
      return s;
    }
  }
  std::string_view line;
  while (lines.Next(&line)) {
    if (!io_internal::IsBlank(line)) {
      return ErrorAt(AtLine(kPly, lines.line_number()),
                     "unexpected data after the last element the header declares");
    }
  }
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------------------------
// Binary data.

struct BinaryInput {
  std::string_view bytes;  // the whole file
  std::endian order;
  std::size_t data_offset;  // where the data starts, just after the header
  std::size_t offset;       // the next byte to read

  std::uint64_t remaining() const { return bytes.size() - offset; }
};

// Bytes one instance of `element` takes at least (lists counted as empty).
std::uint64_t MinRecordSize(const PlyElement& element) {
  std::uint64_t size = 0;
  for (const PlyProperty& property : element.properties) {
    size += property.list_count_type ? property.list_count_type->size : property.type.size;
  }
  return size;
}

bool HasLists(const PlyElement& element) {
  for (const PlyProperty& property : element.properties) {
    if (property.list_count_type) return true;
  }
  return false;
}

// Fails, before anything is allocated, when the bytes left cannot hold `element.count` instances.
absl::Status CheckBinaryCountFits(const PlyElement& element, const BinaryInput& in) {
  const std::uint64_t min_size = MinRecordSize(element);
  if (min_size == 0 || element.count <= in.remaining() / min_size) return absl::OkStatus();
  return ErrorAt(
      AtOffset(kPly, in.offset),
      absl::StrCat("header declares ", element.count, " ", PluralName(element), " (",
                   HasLists(element) ? "at least " : "", ByteCount(element.count, min_size),
                   ") but only ", in.remaining(), " bytes ",
                   in.offset == in.data_offset ? "follow the header" : "are left"));
}

// Takes `size` bytes from `in`, or fails naming the property the file ends in.
absl::StatusOr<const char*> TakeBytes(std::uint64_t size, const PlyProperty& property,
                                      const Location& record, BinaryInput& in) {
  if (in.remaining() < size) {
    Location where = record;
    where.position = in.offset;
    return ErrorAt(
        where, absl::StrCat("the file ends inside property '", property.name, "' (it needs ", size,
                            " bytes, ", in.remaining(), " are left)"));
  }
  const char* data = in.bytes.data() + in.offset;
  in.offset += size;
  return data;
}

// Reads one instance of `element` starting at `in.offset`; vertex values go to `*values`.
absl::Status ReadBinaryInstance(const PlyElement& element, const Location& where, BinaryInput& in,
                                PointValues* values, PlyPolygons* polygons) {
  for (const PlyProperty& property : element.properties) {
    if (property.list_count_type) {
      const std::size_t count_offset = in.offset;
      absl::StatusOr<const char*> count_bytes =
          TakeBytes(property.list_count_type->size, property, where, in);
      if (!count_bytes.ok()) return count_bytes.status();
      const double count = DecodeScalar(*count_bytes, *property.list_count_type, in.order);
      if (count < 0) {
        Location at_count = where;
        at_count.position = count_offset;
        return ErrorAt(at_count, absl::StrCat("list '", property.name, "' has a negative count (",
                                              count, ")"));
      }
      const auto items_size = static_cast<std::uint64_t>(count) * property.type.size;
      absl::StatusOr<const char*> items = TakeBytes(items_size, property, where, in);
      if (!items.ok()) return items.status();
      KeepListSize(property, static_cast<std::uint64_t>(count), polygons);
      for (std::uint64_t k = 0;
           polygons != nullptr && property.face_indices && k < static_cast<std::uint64_t>(count);
           ++k) {
        KeepListItem(property,
                     DecodeScalar(*items + k * property.type.size, property.type, in.order),
                     polygons);
      }
      continue;
    }
    absl::StatusOr<const char*> data = TakeBytes(property.type.size, property, where, in);
    if (!data.ok()) return data.status();
    if (property.component != Component::kNotAComponent) {
      (*values)[property.component] = DecodeScalar(*data, property.type, in.order) * property.scale;
    }
  }
  return absl::OkStatus();
}

// Reads every instance of `element`; when `cloud` is set (the vertex element) appends the points.
absl::Status ReadBinaryElement(const PlyElement& element, const PlyHeader& header, BinaryInput& in,
                               PointCloud* cloud, PlyPolygons* polygons) {
  if (absl::Status status = CheckBinaryCountFits(element, in); !status.ok()) return status;
  if (cloud == nullptr && !HasLists(element)) {  // Fixed-size records: nothing to check inside.
    in.offset += element.count * MinRecordSize(element);
    return absl::OkStatus();
  }
  if (cloud != nullptr) {
    io_internal::ReservePoints(element.count, element.count, header.has_normals, cloud,
                               header.has_colors);
  }
  PointValues values{};
  for (std::uint64_t i = 0; i < element.count; ++i) {
    const Location where = {kPly, Location::Unit::kByteOffset, in.offset, element.name, i};
    if (absl::Status s = ReadBinaryInstance(element, where, in, &values, polygons); !s.ok()) {
      return s;
    }
    if (cloud != nullptr) {
      if (absl::Status s = AppendPoint(values, header.has_normals, where, cloud); !s.ok()) return s;
      if (header.has_colors) cloud->colors.push_back(io_internal::ColorOf(values));
    }
  }
  return absl::OkStatus();
}

absl::Status ReadBinaryBody(const PlyHeader& header, std::string_view bytes,
                            std::size_t data_offset, PointCloud* cloud, PlyPolygons* polygons) {
  BinaryInput in = {.bytes = bytes,
                    .order = header.encoding == PlyEncoding::kBinaryBigEndian ? std::endian::big
                                                                              : std::endian::little,
                    .data_offset = data_offset,
                    .offset = data_offset};
  for (const PlyElement& element : header.elements) {
    PointCloud* destination = element.name == kVertex ? cloud : nullptr;
    if (absl::Status s = ReadBinaryElement(element, header, in, destination, polygons); !s.ok()) {
      return s;
    }
  }
  if (!io_internal::IsBlank(bytes.substr(in.offset))) {
    return ErrorAt(AtOffset(kPly, in.offset),
                   absl::StrCat(in.remaining(),
                                " unexpected bytes after the last element the header declares"));
  }
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------------------------
// Writer.

std::string_view PlyFormatName(PlyEncoding encoding) {
  switch (encoding) {
    case PlyEncoding::kAscii:
      return "ascii";
    case PlyEncoding::kBinaryLittleEndian:
      return "binary_little_endian";
    case PlyEncoding::kBinaryBigEndian:
      return "binary_big_endian";
  }
  return "ascii";
}

}  // namespace

namespace io_internal {

absl::StatusOr<CloudFile> ParsePlyFile(std::string_view bytes) {
  LineCursor lines(bytes);
  absl::StatusOr<PlyHeader> header = ParsePlyHeader(lines);
  if (!header.ok()) return header.status();
  PointCloud cloud;
  const absl::Status status = header->encoding == PlyEncoding::kAscii
                                  ? ReadAsciiBody(*header, lines, &cloud, nullptr)
                                  : ReadBinaryBody(*header, bytes, lines.offset(), &cloud, nullptr);
  if (!status.ok()) return status;
  absl::StatusOr<PointCloud> finished = FinishCloud(kPly, std::move(cloud));
  if (!finished.ok()) return finished.status();
  CloudFile file{*std::move(finished), {}};
  if (!header->ignored.empty()) {
    file.notes.push_back(absl::StrCat("PLY: vertex properties read and ignored: ",
                                      absl::StrJoin(header->ignored, ", ")));
  }
  return file;
}

std::string PlyBytes(const PointCloud& cloud, PlyEncoding encoding, const ScalarFields& scalars) {
  std::string out = absl::StrCat("ply\nformat ", ToAbsl(PlyFormatName(encoding)),
                                 " 1.0\ncomment written by mlsreg\nelement vertex ", cloud.size(),
                                 "\nproperty double x\nproperty double y\nproperty double z\n");
  if (WritesNormals(cloud)) out += "property double nx\nproperty double ny\nproperty double nz\n";
  for (const auto& [name, values] : scalars) absl::StrAppend(&out, "property float ", name, "\n");
  if (WritesColors(cloud)) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out += "end_header\n";
  const RecordLayout layout{.scalars = &scalars, .colors = ColorEncoding::kChannels};
  switch (encoding) {
    case PlyEncoding::kAscii:
      AppendRecordsAsText(cloud, layout, ' ', &out);
      break;
    case PlyEncoding::kBinaryLittleEndian:
      AppendRecordsAsBinary(cloud, layout, std::endian::little, &out);
      break;
    case PlyEncoding::kBinaryBigEndian:
      AppendRecordsAsBinary(cloud, layout, std::endian::big, &out);
      break;
  }
  return out;
}

}  // namespace io_internal

absl::StatusOr<PointCloud> ParsePly(std::string_view bytes) {
  absl::StatusOr<CloudFile> file = io_internal::ParsePlyFile(bytes);
  if (!file.ok()) return file.status();
  return std::move(file->cloud);
}

absl::StatusOr<TriangleMesh> ParsePlyMesh(std::string_view bytes) {
  LineCursor lines(bytes);
  absl::StatusOr<PlyHeader> header = ParsePlyHeader(lines);
  if (!header.ok()) return header.status();
  bool has_faces = false;
  for (PlyElement& element : header->elements) {
    for (PlyProperty& property : element.properties) {
      if (element.name == "face" && property.list_count_type &&
          (property.name == "vertex_indices" || property.name == "vertex_index")) {
        property.face_indices = has_faces = true;
      }
    }
  }
  if (!has_faces) {
    return absl::InvalidArgumentError(
        "PLY header has no \"face\" element with a \"vertex_indices\" list: not a mesh");
  }
  PointCloud cloud;
  PlyPolygons polygons;
  const absl::Status status =
      header->encoding == PlyEncoding::kAscii
          ? ReadAsciiBody(*header, lines, &cloud, &polygons)
          : ReadBinaryBody(*header, bytes, lines.offset(), &cloud, &polygons);
  if (!status.ok()) return status;
  return io_internal::TriangulatePolygons("PLY", std::move(cloud.points), polygons.sizes,
                                          polygons.indices);
}

std::string SerializePly(const PointCloud& cloud, PlyEncoding encoding) {
  return io_internal::PlyBytes(cloud, encoding, {});
}

}  // namespace mlsreg
