// Reading and writing point clouds: PLY, PCD, XYZ/CSV and NumPy .npy files.
//
// Readers never trust a file. Every successful parse returns a cloud that passes
// ValidatePointCloud(cloud, 1): at least one point, all coordinates finite, and either no normals
// or one unit normal per point. Anything else is an error, never a partial read:
//   * absl::InvalidArgumentError for malformed data (truncated file, a header whose counts do not
//     match the data, a token that is not a number, NaN/Inf coordinates, a zero-length normal,
//     extra data after the last element, no points at all, ...);
//   * absl::UnimplementedError for valid files using a feature mlsreg does not support (PCD
//     DATA binary_compressed, unknown PCD VERSION).
// Error messages say what is wrong and where: "PLY line 14, vertex 2: ..." for text data,
// "PLY byte offset 1234, vertex 2: ..." for binary data. Line numbers count from 1; byte offsets
// count from 0 at the start of the file; point/vertex indices count from 0 (as in
// ValidatePointCloud).
//
// Normals read from a file are normalised (a normal already unit to within 1e-12 in squared
// length is kept bit for bit, so files written by mlsreg round-trip exactly). A normal of zero
// length or with a non-finite component is an error.
//
// Format notes:
//   PLY  Header "ply", "format ascii|binary_little_endian|binary_big_endian 1.0", "comment" and
//        "obj_info" lines, any number of elements in any order. The "vertex" element must have
//        scalar properties x, y, z of any PLY numeric type (char uchar short ushort int uint
//        float double, or int8 uint8 int16 uint16 int32 uint32 float32 float64) and may have nx,
//        ny, nz (all three or none). Other properties and elements, including list properties,
//        are checked and skipped. In ASCII every element instance is one line. ASCII values are
//        parsed as double whatever the declared type (the text is taken at its word).
//   PCD  Version 0.7 (and 0.6) headers with DATA ascii or binary. Fields x, y, z are required,
//        normal_x, normal_y, normal_z optional (all three or none); other fields of any TYPE/SIZE/
//        COUNT (rgb, curvature, padding "_") are skipped. VIEWPOINT, when present, is stored as
//        cloud.viewpoint (its translation; the orientation is not kept). Points whose x, y, z are
//        all NaN (PCL's marker for a missing point in an organised cloud) are rejected with an
//        error naming the point: mlsreg requires finite coordinates, so remove them first.
//   XYZ  One point per line, fields separated by whitespace and/or a single comma (so .csv works
//        too): "x y z" or "x y z nx ny nz", the same count on every line. Blank lines and lines
//        starting with '#' are skipped; a first line with no numeric field is a header and is
//        skipped (e.g. "x,y,z").
//   NPY  A NumPy array file (format 1.0, 2.0 or 3.0) holding a C-order float64 or float32 array of
//        shape (N, 3) or (N, 6) (x y z, or x y z nx ny nz), either byte order. Written as
//        little-endian float64, shape (N, 3) or (N, 6).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };
enum class PcdEncoding { kAscii, kBinary };

// Parse a whole file held in memory (see the notes above for what each accepts).
absl::StatusOr<PointCloud> ParsePly(std::string_view bytes);
absl::StatusOr<PointCloud> ParsePcd(std::string_view bytes);
absl::StatusOr<PointCloud> ParseXyz(std::string_view bytes);  // also CSV
absl::StatusOr<PointCloud> ParseNpy(std::string_view bytes);

// Serialise a cloud. Coordinates and normals are written as doubles (binary float64, or text with
// 17 significant digits), so parsing the result gives back the same values bit for bit. The cloud
// is not validated here; WritePointCloud does that.
//   PLY: element vertex N with double x y z (and nx ny nz when the cloud has normals).
//   PCD: FIELDS x y z [normal_x normal_y normal_z], SIZE 8, TYPE F, COUNT 1, WIDTH N, HEIGHT 1,
//        VIEWPOINT from cloud.viewpoint (identity orientation; 0 0 0 1 0 0 0 when unset).
//        Note that parsing always sets viewpoint, since the written header always has VIEWPOINT.
//   XYZ: "x y z [nx ny nz]" per line, no header.
std::string SerializePly(const PointCloud& cloud, PlyEncoding encoding);
std::string SerializePcd(const PointCloud& cloud, PcdEncoding encoding);
std::string SerializeXyz(const PointCloud& cloud);
std::string SerializeNpy(const PointCloud& cloud);

// Reads a file, choosing the format by extension (case-insensitive): .ply, .pcd, .xyz/.txt/.csv,
// .npy. Errors: unknown or missing extension -> InvalidArgument naming it; file does not exist ->
// NotFound; cannot be read -> Unavailable (both naming the path); a parse error keeps its code and
// its message is prefixed with "<path>: ".
absl::StatusOr<PointCloud> ReadPointCloud(const std::string& path);

// The whole file, the one file reader of the project (clouds, meshes, sidecars, configs, keys).
// NotFound when it or a directory on its path does not exist, else Unavailable; the message
// names the path and the system's reason.
absl::StatusOr<std::string> ReadFileBytes(const std::string& path);

struct WriteOptions {
  PlyEncoding ply = PlyEncoding::kBinaryLittleEndian;
  PcdEncoding pcd = PcdEncoding::kBinary;
};

// Per-point attributes for viewers: CloudCompare and MeshLab show a float vertex property as a
// scalar field and uchar red / green / blue as colours.
struct PointAttributes {
  std::vector<std::array<std::uint8_t, 3>> colors;                  // empty, or one per point
  std::vector<std::pair<std::string, std::vector<float>>> scalars;  // (name, one per point)
};

// `cloud` (points as double x y z, normals when it has them) with `attributes`, as a binary
// little-endian PLY (scalars as float properties after the normals, then red green blue).
// InvalidArgument when an attribute has the wrong length, a scalar name is not [A-Za-z0-9_]+
// or clashes with x y z nx ny nz red green blue, or the cloud does not pass
// ValidatePointCloud(cloud, 1); file errors as for WritePointCloud. Our reader skips the extra
// properties, so the file reads back as the cloud.
absl::Status WritePlyWithAttributes(const PointCloud& cloud, const PointAttributes& attributes,
                                    const std::string& path);

// Writes `cloud` to `path` in the format chosen by its extension, as ReadPointCloud. The cloud must
// pass ValidatePointCloud(cloud, 1) (InvalidArgument otherwise). A missing directory gives
// NotFound, any other failure to write Unavailable, naming the path. The file is written in
// place: a failure part-way may leave a partial file behind.
absl::Status WritePointCloud(const PointCloud& cloud, const std::string& path,
                             const WriteOptions& options = {});

}  // namespace mlsreg
