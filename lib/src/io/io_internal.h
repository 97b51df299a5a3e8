// Helpers shared by the PLY, PCD and XYZ readers and writers (io_*.cc). Not part of the public API.
//
// Contents, top-down: where an error is (Location), walking text (LineCursor, NextToken),
// parsing numbers, decoding/encoding binary scalars, and turning the values read for one point
// into a validated point of a PointCloud.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/io/io.h"

namespace mlsreg::io_internal {

// Debian's absl 20220623 has its own string_view type; convert explicitly.
inline absl::string_view ToAbsl(std::string_view s) {
  return absl::string_view(s.data(), s.size());
}

// ---------------------------------------------------------------------------------------------
// Where an error is, rendered as "PLY line 14, vertex 2" or "PCD byte offset 96, point 3".

struct Location {
  enum class Unit { kLine, kByteOffset };

  std::string_view format;  // "PLY", "PCD" or "XYZ"
  Unit unit;
  std::uint64_t position;      // line number (from 1) or byte offset (from 0, start of file)
  std::string_view item = {};  // "vertex", "point", another element name, or empty
  std::uint64_t index = 0;     // index of the item (from 0) when `item` is set
};

inline Location AtLine(std::string_view format, std::uint64_t line) {
  return {format, Location::Unit::kLine, line};
}
inline Location AtOffset(std::string_view format, std::uint64_t offset) {
  return {format, Location::Unit::kByteOffset, offset};
}

inline std::string ToString(const Location& where) {
  std::string text = absl::StrCat(ToAbsl(where.format),
                                  where.unit == Location::Unit::kLine ? " line " : " byte offset ",
                                  where.position);
  if (!where.item.empty()) absl::StrAppend(&text, ", ", ToAbsl(where.item), " ", where.index);
  return text;
}

// InvalidArgument "<where>: <what>".
inline absl::Status ErrorAt(const Location& where, std::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat(ToString(where), ": ", ToAbsl(what)));
}

// A token from a file, quoted for an error message: escaped, and cut short when long.
inline std::string Quote(std::string_view token) {
  constexpr std::size_t kMaxShown = 32;
  const bool cut = token.size() > kMaxShown;
  return absl::StrCat("'", absl::CHexEscape(ToAbsl(token.substr(0, kMaxShown))),
                      cut ? "...'" : "'");
}

// "N bytes", spelled out even when count * bytes_each does not fit in 64 bits.
inline std::string ByteCount(std::uint64_t count, std::uint64_t bytes_each) {
  if (bytes_each != 0 && count > UINT64_MAX / bytes_each) {
    return absl::StrCat("more than ", UINT64_MAX, " bytes");
  }
  return absl::StrCat(count * bytes_each, " bytes");
}

// ---------------------------------------------------------------------------------------------
// Text.

inline bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

inline bool IsBlank(std::string_view text) {
  return std::all_of(text.begin(), text.end(), [](char c) { return IsSpace(c) || c == '\n'; });
}

// Walks `text` line by line. A line ends at '\n' (which is not part of it); a '\r' before the
// '\n' is dropped too, so "\r\n" files read the same.
class LineCursor {
 public:
  explicit LineCursor(std::string_view text) : text_(text) {}

  // Sets `*line` to the next line and returns true, or returns false at the end of the text.
  bool Next(std::string_view* line) {
    if (offset_ >= text_.size()) return false;
    const std::size_t newline = text_.find('\n', offset_);
    const std::size_t end = newline == std::string_view::npos ? text_.size() : newline;
    *line = text_.substr(offset_, end - offset_);
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    offset_ = newline == std::string_view::npos ? text_.size() : newline + 1;
    ++line_number_;
    return true;
  }

  // Number (from 1) of the line last returned by Next; 0 before the first call.
  std::uint64_t line_number() const { return line_number_; }
  // Byte offset where the next line starts: right after the last line's '\n'.
  std::size_t offset() const { return offset_; }
  // Everything not yet returned.
  std::string_view rest() const { return text_.substr(offset_); }

 private:
  std::string_view text_;
  std::size_t offset_ = 0;
  std::uint64_t line_number_ = 0;
};

// Removes the next whitespace-separated token from the front of `*rest` into `*token`; returns
// false when only whitespace is left.
inline bool NextToken(std::string_view* rest, std::string_view* token) {
  std::size_t begin = 0;
  while (begin < rest->size() && IsSpace((*rest)[begin])) ++begin;
  if (begin == rest->size()) {
    *rest = {};
    return false;
  }
  std::size_t end = begin;
  while (end < rest->size() && !IsSpace((*rest)[end])) ++end;
  *token = rest->substr(begin, end - begin);
  rest->remove_prefix(end);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Files (io.cc).

// The extension of the last path component, lower-cased, with its dot (".ply"); empty if none.
std::string LowerCaseExtension(const std::string& path);
using ::mlsreg::ReadFileBytes;  // io.h

// ---------------------------------------------------------------------------------------------
// Numbers.

// Parses a whole token as a double with std::from_chars: decimal or scientific notation, with an
// optional leading '+' or '-'; "nan" and "inf" are accepted (callers reject non-finite values with
// a message saying which value). Returns nullopt for anything else, including out-of-range values.
inline std::optional<double> ParseDouble(std::string_view token) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '-') token.remove_prefix(1);
  double value = 0.0;
  const char* const end = token.data() + token.size();
  const auto [stop, error] = std::from_chars(token.data(), end, value);
  if (error != std::errc() || stop != end) return std::nullopt;
  return value;
}

// Parses a whole token as a non-negative decimal integer (header counts, list lengths).
inline std::optional<std::uint64_t> ParseUint64(std::string_view token) {
  std::uint64_t value = 0;
  const char* const end = token.data() + token.size();
  const auto [stop, error] = std::from_chars(token.data(), end, value);
  if (token.empty() || error != std::errc() || stop != end) return std::nullopt;
  return value;
}

// Appends `value` as text with 17 significant digits (printf "%.17g"), which parses back to the
// same double.
inline void AppendDoubleText(double value, std::string* out) {
  char buffer[32];
  const auto result =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general, 17);
  out->append(buffer, result.ptr);
}

// ---------------------------------------------------------------------------------------------
// Binary scalars. Always memcpy'd (never a reinterpret_cast of unaligned file bytes) and
// byte-swapped when the file's byte order is not the host's.

struct ScalarType {
  enum class Kind : std::uint8_t { kSigned, kUnsigned, kFloat };
  Kind kind;
  std::uint8_t size;  // bytes: 1, 2, 4 or 8 (4 or 8 for kFloat)
};

// The T stored at `data`, its bytes reversed when `swap` (the file's byte order is not ours).
// The copy has a fixed size: a variable one cost a LiDAR scan's reading a tenth of a
// registration.
template <typename T>
T LoadAs(const char* data, bool swap) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, data, sizeof(T));
  if (swap) std::reverse(bytes, bytes + sizeof(T));
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return value;
}

// Reads the scalar of `type` stored at `data` in byte order `order`, as a double.
inline double DecodeScalar(const char* data, ScalarType type, std::endian order) {
  const bool swap = order != std::endian::native;
  using Kind = ScalarType::Kind;
  switch (type.kind) {
    case Kind::kFloat:
      return type.size == 4 ? LoadAs<float>(data, swap) : LoadAs<double>(data, swap);
    case Kind::kSigned:
      switch (type.size) {
        case 1:
          return LoadAs<std::int8_t>(data, swap);
        case 2:
          return LoadAs<std::int16_t>(data, swap);
        case 4:
          return LoadAs<std::int32_t>(data, swap);
        default:
          return static_cast<double>(LoadAs<std::int64_t>(data, swap));
      }
    case Kind::kUnsigned:
      switch (type.size) {
        case 1:
          return LoadAs<std::uint8_t>(data, swap);
        case 2:
          return LoadAs<std::uint16_t>(data, swap);
        case 4:
          return LoadAs<std::uint32_t>(data, swap);
        default:
          return static_cast<double>(LoadAs<std::uint64_t>(data, swap));
      }
  }
  return 0.0;  // Unreachable: every Kind is handled above.
}

// Appends the 8 bytes of `value` in byte order `order`.
inline void AppendDoubleBinary(double value, std::endian order, std::string* out) {
  char bytes[sizeof(double)];
  std::memcpy(bytes, &value, sizeof(double));
  if (order != std::endian::native) std::reverse(bytes, bytes + sizeof(double));
  out->append(bytes, sizeof(double));
}

// ---------------------------------------------------------------------------------------------
// Points.

// The values a reader collects for one point, indexed by Component. Colour channels are on the
// 0-255 scale once read (rounded and clamped when kept).
enum Component : int {
  kX = 0,
  kY,
  kZ,
  kNormalX,
  kNormalY,
  kNormalZ,
  kRed,
  kGreen,
  kBlue,
  kNotAComponent = -1
};
using PointValues = std::array<double, 9>;

// The colour of collected values (NaN reads as 0).
inline Rgb ColorOf(const PointValues& values) {
  Rgb color;
  for (int k = 0; k < 3; ++k) {
    const double v = values[kRed + k];
    color[k] = static_cast<std::uint8_t>(v >= 255.0 ? 255 : v > 0.0 ? std::lround(v) : 0);
  }
  return color;
}

inline constexpr std::array<std::string_view, 3> kAxisNames = {"x", "y", "z"};

// Makes `*normal` unit length. A normal already unit to within 1e-12 in squared length is left
// bit for bit as it is, so normals written by mlsreg round-trip exactly.
inline absl::Status NormalizeNormal(const Location& where, Vec3* normal) {
  const auto describe = [&] {
    return absl::StrCat("normal (", normal->x(), ", ", normal->y(), ", ", normal->z(), ")");
  };
  if (!normal->allFinite()) return ErrorAt(where, describe() + " has a non-finite component");
  if (std::abs(normal->squaredNorm() - 1.0) <= 1e-12) return absl::OkStatus();
  const double largest = normal->cwiseAbs().maxCoeff();
  if (!(largest > 0.0)) return ErrorAt(where, describe() + " has zero length");
  *normal /= largest;  // Largest component now +-1: no overflow or subnormal precision loss below.
  *normal /= normal->norm();
  return absl::OkStatus();
}

// Checks the values read for one point (finite coordinates; a finite, non-zero normal when
// `with_normal`) and appends the point, and its normalised normal, to `*cloud`.
inline absl::Status AppendPoint(const PointValues& values, bool with_normal, const Location& where,
                                PointCloud* cloud) {
  const Vec3 point(values[kX], values[kY], values[kZ]);
  if (!point.allFinite()) {
    if (point.array().isNaN().all()) {
      return ErrorAt(where,
                     "x, y and z are all NaN (the marker PCL uses for a missing point); mlsreg "
                     "requires finite coordinates, so remove such points first");
    }
    for (int axis = 0; axis < 3; ++axis) {
      if (!std::isfinite(point[axis])) {
        return ErrorAt(where, absl::StrCat("coordinate ", ToAbsl(kAxisNames[axis]),
                                           " is not finite (", point[axis], ")"));
      }
    }
  }
  if (with_normal) {
    Vec3 normal(values[kNormalX], values[kNormalY], values[kNormalZ]);
    if (absl::Status status = NormalizeNormal(where, &normal); !status.ok()) return status;
    cloud->normals.push_back(normal);
  }
  cloud->points.push_back(point);
  return absl::OkStatus();
}

// Reserves room for the `declared` points of a header, but for no more than `max_possible`, the
// most the bytes left could hold, so a header that lies cannot make a reader allocate much.
inline void ReservePoints(std::uint64_t declared, std::uint64_t max_possible, bool with_normals,
                          PointCloud* cloud, bool with_colors = false) {
  const std::uint64_t count = std::min(declared, max_possible);
  cloud->points.reserve(count);
  if (with_normals) cloud->normals.reserve(count);
  if (with_colors) cloud->colors.reserve(count);
}

// The most lines of `values_per_line` text values that `available` bytes can hold: each value
// takes at least a character and a separator (or the newline).
inline std::uint64_t MaxTextLines(std::uint64_t available, std::uint64_t values_per_line) {
  if (values_per_line == 0) return available + 1;
  if (values_per_line > available) return 0;  // Also keeps 2 * values_per_line from overflowing.
  return (available + 1) / (2 * values_per_line);
}

// The final check of every reader: at least one point, and the PointCloud invariants.
inline absl::StatusOr<PointCloud> FinishCloud(std::string_view format, PointCloud cloud) {
  if (cloud.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(ToAbsl(format), " file contains no points"));
  }
  if (absl::Status status = ValidatePointCloud(cloud, 1); !status.ok()) return status;
  return cloud;
}

// ---------------------------------------------------------------------------------------------
// Writers.

// True when a writer should write normals: there is exactly one per point.
inline bool WritesNormals(const PointCloud& cloud) {
  return cloud.has_normals() && cloud.normals.size() == cloud.points.size();
}

// True when a writer should write colours: there is exactly one per point.
inline bool WritesColors(const PointCloud& cloud) {
  return cloud.has_colors() && cloud.colors.size() == cloud.points.size();
}

// Scalar fields written beside the points: (name, one value per point).
using ScalarFields = std::vector<std::pair<std::string, std::vector<float>>>;

// How a format stores a colour: three channels (PLY uchar red green blue, text r g b), or PCL's
// rgb, one 32-bit word 0x00RRGGBB stored as a float.
enum class ColorEncoding { kChannels, kPackedFloat };

inline std::uint32_t PackRgb(const Rgb& c) {
  return (std::uint32_t{c[0]} << 16) | (std::uint32_t{c[1]} << 8) | std::uint32_t{c[2]};
}
inline Rgb UnpackRgb(std::uint32_t packed) {
  return {static_cast<std::uint8_t>(packed >> 16), static_cast<std::uint8_t>(packed >> 8),
          static_cast<std::uint8_t>(packed)};
}

// What one written record holds, in this order: x y z, nx ny nz (when the cloud has a normal per
// point), the scalars, the colour (when the cloud has a colour per point).
struct RecordLayout {
  const ScalarFields* scalars = nullptr;  // may be null
  ColorEncoding colors = ColorEncoding::kChannels;
};

// Appends `value` as text with 9 significant digits, which parses back to the same float.
inline void AppendFloatText(float value, std::string* out) {
  char buffer[32];
  const auto result =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::general, 9);
  out->append(buffer, result.ptr);
}

// Appends one line per point, fields separated by `separator`: coordinates and normals with 17
// significant digits, scalars with 9, colours as integers (or PCL's packed float).
inline void AppendRecordsAsText(const PointCloud& cloud, const RecordLayout& layout, char separator,
                                std::string* out) {
  const bool with_normals = WritesNormals(cloud);
  const bool with_colors = WritesColors(cloud);
  out->reserve(out->size() + cloud.size() * (with_normals ? 150 : 75));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (k > 0) *out += separator;
      AppendDoubleText(cloud.points[i][k], out);
    }
    for (int k = 0; with_normals && k < 3; ++k) {
      *out += separator;
      AppendDoubleText(cloud.normals[i][k], out);
    }
    for (std::size_t f = 0; layout.scalars != nullptr && f < layout.scalars->size(); ++f) {
      *out += separator;
      AppendFloatText((*layout.scalars)[f].second[i], out);
    }
    if (with_colors && layout.colors == ColorEncoding::kPackedFloat) {
      *out += separator;
      AppendDoubleText(std::bit_cast<float>(PackRgb(cloud.colors[i])), out);
    } else if (with_colors) {
      for (std::uint8_t c : cloud.colors[i]) {
        *out += separator;
        absl::StrAppend(out, static_cast<int>(c));
      }
    }
    *out += '\n';
  }
}

// Appends the records of every point in byte order `order`: coordinates and normals as 8-byte
// doubles, scalars as 4-byte floats, colours as three bytes (or PCL's packed 4-byte word).
inline void AppendRecordsAsBinary(const PointCloud& cloud, const RecordLayout& layout,
                                  std::endian order, std::string* out) {
  const bool with_normals = WritesNormals(cloud);
  const bool with_colors = WritesColors(cloud);
  const auto append_word = [&](std::uint32_t bits) {
    char bytes[4];
    std::memcpy(bytes, &bits, 4);
    if (order != std::endian::native) std::reverse(bytes, bytes + 4);
    out->append(bytes, 4);
  };
  out->reserve(out->size() + cloud.size() * (with_normals ? 48 : 24));
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) AppendDoubleBinary(cloud.points[i][k], order, out);
    for (int k = 0; with_normals && k < 3; ++k) AppendDoubleBinary(cloud.normals[i][k], order, out);
    for (std::size_t f = 0; layout.scalars != nullptr && f < layout.scalars->size(); ++f) {
      append_word(std::bit_cast<std::uint32_t>((*layout.scalars)[f].second[i]));
    }
    if (with_colors && layout.colors == ColorEncoding::kPackedFloat) {
      append_word(PackRgb(cloud.colors[i]));
    } else if (with_colors) {
      for (std::uint8_t c : cloud.colors[i]) *out += static_cast<char>(c);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The readers and writers behind the public functions (io_ply.cc, io_pcd.cc, io_xyz.cc,
// io_npy.cc): whole files with their notes, and files with scalar fields.

absl::StatusOr<CloudFile> ParsePlyFile(std::string_view bytes);
absl::StatusOr<CloudFile> ParsePcdFile(std::string_view bytes);
absl::StatusOr<CloudFile> ParseXyzFile(std::string_view bytes, const ReadOptions& options);
absl::StatusOr<CloudFile> ParseNpyFile(std::string_view bytes, const ReadOptions& options);

std::string PlyBytes(const PointCloud& cloud, PlyEncoding encoding, const ScalarFields& scalars);
std::string PcdBytes(const PointCloud& cloud, PcdEncoding encoding, const ScalarFields& scalars);
// A header line naming the columns when there are more than x y z, then the records.
std::string XyzText(const PointCloud& cloud, const ScalarFields& scalars, char separator);
// float64 (N, k): x y z [nx ny nz] [scalars] [r g b] when `with_colors`.
std::string NpyBytes(const PointCloud& cloud, const ScalarFields& scalars, bool with_colors);

// ---------------------------------------------------------------------------------------------
// Meshes (mesh_io.cc).

// Splits polygon i (sizes[i] corners, taken in order from `indices`) into a fan of triangles,
// checking every index is an integer in range; the result passes ValidateTriangleMesh.
absl::StatusOr<TriangleMesh> TriangulatePolygons(std::string_view format,
                                                 std::vector<Vec3> vertices,
                                                 const std::vector<std::uint32_t>& sizes,
                                                 const std::vector<double>& indices);

}  // namespace mlsreg::io_internal
