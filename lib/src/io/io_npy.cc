// NumPy .npy reader and writer. See mlsreg/io.h for what is accepted.
//
// A .npy file is a magic string, a version, a little header (a Python dict literal giving the
// element type, the memory order and the shape) padded to 16 bytes (64 in newer writers), then
// the raw array.

#include <bit>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "io_internal.h"
#include "mlsreg/io/io.h"
#include "table_columns.h"

namespace mlsreg {
namespace {

using io_internal::ToAbsl;

constexpr std::string_view kMagic = "\x93NUMPY";
constexpr std::uint64_t kMaxColumns = 4096;

absl::Status NpyError(std::string_view what) {
  return absl::InvalidArgumentError(absl::StrCat("NPY header: ", ToAbsl(what)));
}

// The text of the value of `key` in the header dict, up to the next top-level ',' or '}'.
absl::StatusOr<std::string_view> DictValue(std::string_view dict, std::string_view key) {
  const std::string quoted_single = absl::StrCat("'", ToAbsl(key), "'");
  const std::string quoted_double = absl::StrCat("\"", ToAbsl(key), "\"");
  std::size_t at = dict.find(quoted_single);
  if (at == std::string_view::npos) at = dict.find(quoted_double);
  if (at == std::string_view::npos) return NpyError(absl::StrCat("no '", ToAbsl(key), "' entry"));
  std::size_t colon = dict.find(':', at + key.size() + 2);
  if (colon == std::string_view::npos)
    return NpyError(absl::StrCat("'", ToAbsl(key), "' has no value"));
  std::size_t begin = colon + 1;
  while (begin < dict.size() && io_internal::IsSpace(dict[begin])) ++begin;
  std::size_t end = begin;
  int depth = 0;
  while (end < dict.size()) {
    const char c = dict[end];
    if (c == '(') ++depth;
    if (c == ')') --depth;
    if (depth == 0 && (c == ',' || c == '}')) break;
    ++end;
    if (depth == 0 && c == ')') break;
  }
  std::string_view value = dict.substr(begin, end - begin);
  while (!value.empty() && io_internal::IsSpace(value.back())) value.remove_suffix(1);
  return value;
}

struct NpyLayout {
  std::endian order = std::endian::little;
  io_internal::ScalarType type{io_internal::ScalarType::Kind::kFloat, 8};
  std::uint64_t rows = 0;
  std::uint64_t columns = 0;
};

absl::StatusOr<NpyLayout> ParseHeaderDict(std::string_view dict) {
  NpyLayout layout;
  absl::StatusOr<std::string_view> descr = DictValue(dict, "descr");
  if (!descr.ok()) return descr.status();
  std::string_view d = *descr;
  if (d.size() >= 2 && (d.front() == '\'' || d.front() == '"')) d = d.substr(1, d.size() - 2);
  if (d == "<f8" || d == "<f4" || d == ">f8" || d == ">f4" || d == "=f8" || d == "=f4") {
    layout.order = d[0] == '>' ? std::endian::big : std::endian::little;
    layout.type.size = d[2] == '8' ? 8 : 4;
  } else {
    return absl::UnimplementedError(
        absl::StrCat("NPY header: element type ", io_internal::Quote(d),
                     " is not supported; mlsreg reads float64 or float32 arrays ('<f8', '<f4')"));
  }
  absl::StatusOr<std::string_view> fortran = DictValue(dict, "fortran_order");
  if (!fortran.ok()) return fortran.status();
  if (*fortran != "False") {
    return absl::UnimplementedError(
        "NPY header: the array is in Fortran order; save it C-ordered (numpy.ascontiguousarray)");
  }
  absl::StatusOr<std::string_view> shape = DictValue(dict, "shape");
  if (!shape.ok()) return shape.status();
  std::string_view s = *shape;
  if (s.size() < 2 || s.front() != '(' || s.back() != ')') {
    return NpyError(absl::StrCat("shape ", io_internal::Quote(s), " is not a tuple"));
  }
  s = s.substr(1, s.size() - 2);
  std::vector<std::uint64_t> dims;
  std::string_view token;
  std::string text(s);
  for (char& c : text) {
    if (c == ',') c = ' ';
  }
  std::string_view rest = text;
  while (io_internal::NextToken(&rest, &token)) {
    const std::optional<std::uint64_t> dim = io_internal::ParseUint64(token);
    if (!dim)
      return NpyError(absl::StrCat("shape has a bad dimension ", io_internal::Quote(token)));
    dims.push_back(*dim);
  }
  if (dims.size() != 2 || dims[1] < 3 || dims[1] > kMaxColumns) {
    return absl::InvalidArgumentError(
        absl::StrCat("NPY: the array has shape ", io_internal::Quote(*shape),
                     "; expected (N, k) with 3 <= k <= ", kMaxColumns,
                     ": x y z, then normals, colours or other columns"));
  }
  layout.rows = dims[0];
  layout.columns = dims[1];
  return layout;
}

}  // namespace

namespace io_internal {

absl::StatusOr<CloudFile> ParseNpyFile(std::string_view bytes, const ReadOptions& options) {
  if (bytes.substr(0, kMagic.size()) != kMagic || bytes.size() < 10) {
    return absl::InvalidArgumentError("not a NumPy .npy file: the magic string is missing");
  }
  const auto major = static_cast<unsigned char>(bytes[6]);
  if (major < 1 || major > 3) {
    return absl::UnimplementedError(
        absl::StrCat("NPY format version ", major, " is not supported"));
  }
  const std::size_t length_bytes = major == 1 ? 2 : 4;
  const std::size_t dict_start = 8 + length_bytes;
  if (bytes.size() < dict_start) return NpyError("the file ends inside the header length");
  std::uint64_t dict_length = 0;
  for (std::size_t k = 0; k < length_bytes; ++k) {
    dict_length |= std::uint64_t{static_cast<unsigned char>(bytes[8 + k])} << (8 * k);
  }
  if (bytes.size() - dict_start < dict_length) {
    return NpyError(absl::StrCat("it declares ", dict_length, " bytes but only ",
                                 bytes.size() - dict_start, " follow"));
  }
  absl::StatusOr<NpyLayout> layout = ParseHeaderDict(bytes.substr(dict_start, dict_length));
  if (!layout.ok()) return layout.status();
  const std::size_t data_offset = dict_start + dict_length;
  const std::uint64_t available = bytes.size() - data_offset;
  const std::uint64_t record = layout->columns * layout->type.size;
  if (layout->rows > available / record || layout->rows * record != available) {
    return absl::InvalidArgumentError(absl::StrCat(
        "NPY: the header declares ", layout->rows, " x ", layout->columns, " values (",
        io_internal::ByteCount(layout->rows, record), ") but ", available, " bytes follow it"));
  }
  absl::StatusOr<ColumnLayout> columns =
      options.columns.empty() ? LayoutFromCount(layout->columns)
                              : LayoutFromNames(options.columns, "the columns given");
  if (!columns.ok()) return columns.status();
  if (columns->roles.size() != layout->columns) {
    return absl::InvalidArgumentError(absl::StrCat("NPY: the columns given name ",
                                                   columns->roles.size(),
                                                   " columns but the array has ", layout->columns));
  }
  TableCloud table("NPY", *std::move(columns));
  table.Reserve(layout->rows);
  std::vector<double> values(layout->columns);
  for (std::uint64_t i = 0; i < layout->rows; ++i) {
    const std::size_t offset = data_offset + i * record;
    for (std::uint64_t c = 0; c < layout->columns; ++c) {
      values[c] =
          DecodeScalar(bytes.data() + offset + c * layout->type.size, layout->type, layout->order);
    }
    const Location where = {"NPY", Location::Unit::kByteOffset, offset, "point", i};
    if (absl::Status s = table.AddRow(values.data(), where); !s.ok()) return s;
  }
  return std::move(table).Finish();
}

std::string NpyBytes(const PointCloud& cloud, const ScalarFields& scalars, bool with_colors) {
  const bool colors = with_colors && WritesColors(cloud);
  const std::size_t columns =
      3 + (WritesNormals(cloud) ? 3 : 0) + scalars.size() + (colors ? 3 : 0);
  std::string dict = absl::StrCat("{'descr': '<f8', 'fortran_order': False, 'shape': (",
                                  cloud.size(), ", ", columns, "), }");
  // Magic (6) + version (2) + length (2) + dict + '\n', padded with spaces to a multiple of 64.
  const std::size_t unpadded = 10 + dict.size() + 1;
  dict.append((64 - unpadded % 64) % 64, ' ');
  dict += '\n';
  std::string out(kMagic);
  out += '\x01';
  out += '\x00';
  out += static_cast<char>(dict.size() & 0xff);
  out += static_cast<char>(dict.size() >> 8);
  out += dict;
  const bool normals = WritesNormals(cloud);
  out.reserve(out.size() + cloud.size() * columns * 8);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) AppendDoubleBinary(cloud.points[i][k], std::endian::little, &out);
    for (int k = 0; normals && k < 3; ++k) {
      AppendDoubleBinary(cloud.normals[i][k], std::endian::little, &out);
    }
    for (const auto& [name, values] : scalars) {
      AppendDoubleBinary(values[i], std::endian::little, &out);
    }
    for (int k = 0; colors && k < 3; ++k) {
      AppendDoubleBinary(cloud.colors[i][k], std::endian::little, &out);
    }
  }
  return out;
}

}  // namespace io_internal

absl::StatusOr<PointCloud> ParseNpy(std::string_view bytes) {
  absl::StatusOr<CloudFile> file = io_internal::ParseNpyFile(bytes, {});
  if (!file.ok()) return file.status();
  return std::move(file->cloud);
}

std::string SerializeNpy(const PointCloud& cloud) {
  return io_internal::NpyBytes(cloud, {}, false);
}

}  // namespace mlsreg
