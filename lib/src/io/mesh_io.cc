// Triangle meshes: OFF and OBJ readers, fan triangulation, and ReadTriangleMesh (the PLY mesh
// reader lives with the PLY point reader in io_ply.cc). See mlsreg/mesh_io.h.

#include "mlsreg/io/mesh_io.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "io_internal.h"

namespace mlsreg {
namespace {

using io_internal::AtLine;
using io_internal::ErrorAt;
using io_internal::LineCursor;
using io_internal::NextToken;
using io_internal::Quote;

// The next line with content, with any '#' comment removed; false at the end of the text.
bool NextContentLine(LineCursor& lines, std::string_view* line) {
  while (lines.Next(line)) {
    const std::size_t hash = line->find('#');
    if (hash != std::string_view::npos) *line = line->substr(0, hash);
    if (!io_internal::IsBlank(*line)) return true;
  }
  return false;
}

absl::Status ReadCoordinates(std::string_view* rest, const io_internal::Location& where,
                             Vec3* vertex) {
  std::string_view token;
  for (int axis = 0; axis < 3; ++axis) {
    if (!NextToken(rest, &token)) {
      return ErrorAt(where, absl::StrCat("the vertex has only ", axis, " coordinates"));
    }
    const std::optional<double> value = io_internal::ParseDouble(token);
    if (!value || !std::isfinite(*value)) {
      return ErrorAt(where,
                     absl::StrCat("coordinate ", io_internal::ToAbsl(io_internal::kAxisNames[axis]),
                                  " ", Quote(token), " is not a finite number"));
    }
    (*vertex)[axis] = *value;
  }
  return absl::OkStatus();
}

}  // namespace

namespace io_internal {

absl::StatusOr<TriangleMesh> TriangulatePolygons(std::string_view format,
                                                 std::vector<Vec3> vertices,
                                                 const std::vector<std::uint32_t>& sizes,
                                                 const std::vector<double>& indices) {
  TriangleMesh mesh;
  mesh.vertices = std::move(vertices);
  std::size_t next = 0;
  for (std::size_t polygon = 0; polygon < sizes.size(); ++polygon) {
    const std::uint32_t n = sizes[polygon];
    if (n < 3) {
      return absl::InvalidArgumentError(absl::StrCat(ToAbsl(format), " face ", polygon, " has ", n,
                                                     " corners; a face needs at least 3"));
    }
    std::uint32_t corner[3] = {};
    for (std::uint32_t k = 0; k < n; ++k) {
      const double value = indices[next++];
      if (!(value >= 0.0) || value != std::floor(value) ||
          value >= static_cast<double>(mesh.vertices.size())) {
        return absl::InvalidArgumentError(
            absl::StrCat(ToAbsl(format), " face ", polygon, ": vertex index ", value,
                         " is not one of the ", mesh.vertices.size(), " vertices"));
      }
      const auto index = static_cast<std::uint32_t>(value);
      if (k == 0) corner[0] = index;
      corner[1] = corner[2];
      corner[2] = index;
      if (k >= 2) mesh.triangles.push_back({corner[0], corner[1], corner[2]});
    }
  }
  if (mesh.triangles.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(ToAbsl(format), " file contains no faces"));
  }
  return mesh;
}

}  // namespace io_internal

absl::StatusOr<TriangleMesh> ParseOff(std::string_view bytes) {
  constexpr std::string_view kOff = "OFF";
  LineCursor lines(bytes);
  std::string_view line, token;
  if (!NextContentLine(lines, &line) || !NextToken(&line, &token) || token.size() < 3 ||
      token.substr(token.size() - 3) != kOff) {
    return absl::InvalidArgumentError("not an OFF file: the first line must be \"OFF\"");
  }
  // Counts may follow "OFF" on the same line.
  if (io_internal::IsBlank(line) && !NextContentLine(lines, &line)) {
    return absl::InvalidArgumentError("OFF file ends before the counts line");
  }
  const io_internal::Location counts_at = AtLine(kOff, lines.line_number());
  std::uint64_t counts[2] = {};
  for (std::uint64_t& count : counts) {
    if (!NextToken(&line, &token) || !io_internal::ParseUint64(token)) {
      return ErrorAt(counts_at, "expected \"<vertices> <faces> <edges>\"");
    }
    count = *io_internal::ParseUint64(token);
  }
  const std::uint64_t most = bytes.size() / 2 + 1;  // each item takes two bytes at least
  if (counts[0] > most || counts[1] > most) {
    return ErrorAt(counts_at, "the counts exceed what the file could hold");
  }
  std::vector<Vec3> vertices(counts[0]);
  for (std::uint64_t i = 0; i < counts[0]; ++i) {
    if (!NextContentLine(lines, &line)) {
      return ErrorAt(AtLine(kOff, lines.line_number()),
                     absl::StrCat("the file ends after ", i, " of ", counts[0], " vertices"));
    }
    const io_internal::Location where = {kOff, io_internal::Location::Unit::kLine,
                                         lines.line_number(), "vertex", i};
    if (absl::Status s = ReadCoordinates(&line, where, &vertices[i]); !s.ok()) return s;
  }
  std::vector<std::uint32_t> sizes;
  std::vector<double> indices;
  sizes.reserve(counts[1]);
  for (std::uint64_t f = 0; f < counts[1]; ++f) {
    if (!NextContentLine(lines, &line)) {
      return ErrorAt(AtLine(kOff, lines.line_number()),
                     absl::StrCat("the file ends after ", f, " of ", counts[1], " faces"));
    }
    const io_internal::Location where = {kOff, io_internal::Location::Unit::kLine,
                                         lines.line_number(), "face", f};
    std::optional<std::uint64_t> n;
    if (!NextToken(&line, &token) || !(n = io_internal::ParseUint64(token)) || *n > 1u << 20) {
      return ErrorAt(where, "expected the corner count first");
    }
    sizes.push_back(static_cast<std::uint32_t>(*n));
    for (std::uint64_t k = 0; k < *n; ++k) {
      const std::optional<std::uint64_t> index =
          NextToken(&line, &token) ? io_internal::ParseUint64(token) : std::nullopt;
      if (!index) return ErrorAt(where, absl::StrCat("corner ", k, " is not a vertex index"));
      indices.push_back(static_cast<double>(*index));
    }
  }
  return io_internal::TriangulatePolygons(kOff, std::move(vertices), sizes, indices);
}

absl::StatusOr<TriangleMesh> ParseObj(std::string_view bytes) {
  constexpr std::string_view kObj = "OBJ";
  LineCursor lines(bytes);
  std::string_view line, token;
  std::vector<Vec3> vertices;
  std::vector<std::uint32_t> sizes;
  std::vector<double> indices;
  std::vector<long long> face;
  while (NextContentLine(lines, &line)) {
    if (!NextToken(&line, &token)) continue;
    if (token == "v") {
      const io_internal::Location where = {kObj, io_internal::Location::Unit::kLine,
                                           lines.line_number(), "vertex", vertices.size()};
      Vec3 v;
      if (absl::Status s = ReadCoordinates(&line, where, &v); !s.ok()) return s;
      vertices.push_back(v);
    } else if (token == "f") {
      const io_internal::Location where = {kObj, io_internal::Location::Unit::kLine,
                                           lines.line_number(), "face", sizes.size()};
      face.clear();
      while (NextToken(&line, &token)) {
        const std::string_view first = token.substr(0, token.find('/'));
        long long index = 0;
        const auto [end, error] = std::from_chars(first.data(), first.data() + first.size(), index);
        if (error != std::errc() || end != first.data() + first.size() || index == 0) {
          return ErrorAt(where,
                         absl::StrCat("corner ", Quote(token), " is not a vertex reference"));
        }
        // 1-based; negative counts back from the last vertex defined so far.
        const long long resolved =
            index > 0 ? index - 1 : static_cast<long long>(vertices.size()) + index;
        face.push_back(resolved);
      }
      sizes.push_back(static_cast<std::uint32_t>(face.size()));
      for (long long index : face) indices.push_back(static_cast<double>(index));
    }
  }
  if (vertices.empty()) return absl::InvalidArgumentError("OBJ file contains no vertices");
  return io_internal::TriangulatePolygons(kObj, std::move(vertices), sizes, indices);
}

absl::StatusOr<TriangleMesh> ReadTriangleMesh(const std::string& path) {
  const std::string extension = io_internal::LowerCaseExtension(path);
  absl::StatusOr<TriangleMesh> (*parse)(std::string_view) = nullptr;
  if (extension == ".off") parse = ParseOff;
  if (extension == ".obj") parse = ParseObj;
  if (extension == ".ply") parse = ParsePlyMesh;
  if (parse == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat("unknown mesh file extension '", extension,
                                                   "' in '", path,
                                                   "'; expected .off, .obj or .ply"));
  }
  const absl::StatusOr<std::string> bytes = io_internal::ReadFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  absl::StatusOr<TriangleMesh> mesh = parse(*bytes);
  if (!mesh.ok()) {
    return absl::Status(mesh.status().code(), absl::StrCat(path, ": ", mesh.status().message()));
  }
  return mesh;
}

}  // namespace mlsreg
