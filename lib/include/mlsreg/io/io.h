// Reading and writing point clouds: PLY, PCD, XYZ/CSV and NumPy .npy files.
//
// Readers never trust a file. Every successful parse returns a cloud that passes
// ValidatePointCloud(cloud, 1): at least one point, all coordinates finite, either no normals
// or one unit normal per point, and either no colours or one per point. Anything else is an error,
// never a partial read:
//   * absl::InvalidArgumentError for malformed data (truncated file, a header whose counts do not
//     match the data, a token that is not a number, NaN/Inf coordinates, a zero-length normal,
//     extra data after the last element, no points at all, ...);
//   * absl::UnimplementedError for valid files using a feature mlsreg does not support (an
//     unknown PCD VERSION, a Fortran-ordered or integer NPY array).
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
//        ny, nz and red, green, blue (each all three or none; colours of an integer type are
//        scaled from its range to 0-255, float colours from [0, 1]). Other properties and
//        elements, including list properties, are checked and skipped (the vertex properties
//        skipped are named in CloudFile::notes). In ASCII every element instance is one line.
//        ASCII values are parsed as double whatever the declared type.
//   PCD  Version 0.7 (and 0.6) headers with DATA ascii, binary or binary_compressed (PCL's LZF
//        compression of the fields, one after the other). Fields x, y, z are required,
//        normal_x, normal_y, normal_z optional (all three or none), rgb or rgba (COUNT 1, SIZE
//        4: PCL's packed colour, as F or U) gives colours; other fields of any TYPE/SIZE/COUNT
//        (curvature, intensity, padding "_") are skipped and named in the notes. VIEWPOINT,
//        when present, is stored as cloud.viewpoint (its translation; the orientation is not
//        kept). Points whose x, y, z are all NaN (PCL's marker for a missing point in an
//        organised cloud) are rejected with an error naming the point: mlsreg requires finite
//        coordinates, so remove them first.
//   XYZ  One point per line, fields separated by whitespace and/or a single comma (so .csv works
//        too), the same count on every line. Blank lines and lines starting with '#' are
//        skipped. A first line with no numeric field is a header naming the columns
//        ("x,y,z,r,g,b", "//X Y Z R G B" from CloudCompare); ReadOptions::columns names them
//        instead. Names: x y z (required); nx ny nz or normal_x normal_y normal_z; r g b or red
//        green blue (integers 0-255, or all in [0, 1]); any other name (intensity, ...) is read
//        and ignored, as the notes say. Without names, the first three columns are x y z; of six
//        columns the last three are normals when every row is a unit vector, else colours when
//        every value is an integer from 0 to 255, else the file is refused (name the columns);
//        any other column beyond the third is ignored. A note says how unnamed columns were read.
//   NPY  A NumPy array file (format 1.0, 2.0 or 3.0) holding a C-order float64 or float32 array of
//        shape (N, k), k >= 3, either byte order; its columns are read as an XYZ file's without
//        a header (ReadOptions::columns names them). Written as little-endian float64, shape
//        (N, 3) or (N, 6) (x y z, or x y z nx ny nz).
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

enum class CloudFormat { kPly, kPcd, kXyz, kNpy };

// The format a path's extension names (case-insensitive): .ply, .pcd, .xyz/.txt/.csv, .npy.
// InvalidArgument naming the extension (or its absence) and the ones known.
absl::StatusOr<CloudFormat> CloudFormatOfPath(const std::string& path);

// How to read the fields of files that may not name them (XYZ/CSV text, NPY).
struct ReadOptions {
  // The columns' names in order, e.g. {"x", "y", "z", "r", "g", "b"} or {"x", "y", "z",
  // "intensity"} (see XYZ above). Empty: a text file's header line, or the column count, decides.
  // Only for XYZ and NPY files: PLY and PCD headers name their fields (InvalidArgument).
  std::vector<std::string> columns;
};

// A cloud read from a file, and how its fields were read.
struct CloudFile {
  PointCloud cloud;
  // One sentence each, for the user: fields read and ignored, unnamed columns whose meaning was
  // taken from the data. Empty when the file named everything it holds and all of it was kept.
  std::vector<std::string> notes;
};

// Parse a whole file held in memory (see the notes above for what each accepts).
absl::StatusOr<CloudFile> ParseCloudFile(CloudFormat format, std::string_view bytes,
                                         const ReadOptions& options = {});
absl::StatusOr<PointCloud> ParsePly(std::string_view bytes);
absl::StatusOr<PointCloud> ParsePcd(std::string_view bytes);
absl::StatusOr<PointCloud> ParseXyz(std::string_view bytes);  // also CSV
absl::StatusOr<PointCloud> ParseNpy(std::string_view bytes);

// Serialise a cloud. Coordinates and normals are written as doubles (binary float64, or text with
// 17 significant digits), so parsing the result gives back the same values bit for bit; colours
// as 8-bit channels. The cloud is not validated here; WritePointCloud does that.
//   PLY: element vertex N with double x y z (and nx ny nz when the cloud has normals, uchar red
//        green blue when it has colours).
//   PCD: FIELDS x y z [normal_x normal_y normal_z] [rgb], SIZE 8 (rgb: 4, packed as PCL does),
//        TYPE F, COUNT 1, WIDTH N, HEIGHT 1, VIEWPOINT from cloud.viewpoint (identity
//        orientation; 0 0 0 1 0 0 0 when unset). Note that parsing always sets viewpoint, since
//        the written header always has VIEWPOINT.
//   XYZ: "x y z [nx ny nz] [r g b]" per line, after a header line naming the columns when there
//        are more than x y z.
//   NPY: points and normals; colours are not written.
std::string SerializePly(const PointCloud& cloud, PlyEncoding encoding);
std::string SerializePcd(const PointCloud& cloud, PcdEncoding encoding);
std::string SerializeXyz(const PointCloud& cloud);
std::string SerializeNpy(const PointCloud& cloud);

// Reads a file, choosing the format by extension (CloudFormatOfPath). Errors: unknown or missing
// extension -> InvalidArgument naming it; file does not exist -> NotFound; cannot be read ->
// Unavailable (both naming the path); a parse error keeps its code and its message is prefixed
// with "<path>: ". The notes are prefixed with the path too.
absl::StatusOr<CloudFile> ReadCloudFile(const std::string& path, const ReadOptions& options = {});
// The same, keeping only the cloud.
absl::StatusOr<PointCloud> ReadPointCloud(const std::string& path);

// The whole file, the one file reader of the project (clouds, meshes, sidecars, configs, keys).
// NotFound when it or a directory on its path does not exist, else Unavailable; the message
// names the path and the system's reason.
absl::StatusOr<std::string> ReadFileBytes(const std::string& path);

struct WriteOptions {
  PlyEncoding ply = PlyEncoding::kBinaryLittleEndian;
  PcdEncoding pcd = PcdEncoding::kBinary;
};

// Per-point scalar fields for viewers (CloudCompare and MeshLab show a float vertex property
// as a scalar field): (name, one value per point).
struct PointAttributes {
  std::vector<std::pair<std::string, std::vector<float>>> scalars;
};

// `cloud` (points as double x y z, normals and colours when it has them) with `attributes`, in
// the format its path's extension names:
//   PLY  binary little-endian, the scalars as float properties after the normals, then uchar
//        red green blue;
//   PCD  binary, the scalars as F 4 fields after the normals, then rgb;
//   XYZ  a header line naming the columns (x y z [nx ny nz] [scalars] [r g b]), then one line
//        per point ("," between fields for .csv, a space otherwise);
//   NPY  float64 (N, k), columns in the same order as XYZ's header (numbers only: the names are
//        in the documentation of the writer that calls this).
// InvalidArgument when an attribute has the wrong length, a scalar name is not [A-Za-z0-9_]+
// or clashes with x y z nx ny nz red green blue r g b rgb, or the cloud does not pass
// ValidatePointCloud(cloud, 1); file errors as for WritePointCloud. Our readers skip the
// scalars (and say so), so the file reads back as the cloud.
absl::Status WriteCloudWithAttributes(const PointCloud& cloud, const PointAttributes& attributes,
                                      const std::string& path);

// Writes `cloud` to `path` in the format chosen by its extension, as ReadPointCloud. The cloud must
// pass ValidatePointCloud(cloud, 1) (InvalidArgument otherwise). A missing directory gives
// NotFound, any other failure to write Unavailable, naming the path. The file is written in
// place: a failure part-way may leave a partial file behind.
absl::Status WritePointCloud(const PointCloud& cloud, const std::string& path,
                             const WriteOptions& options = {});

}  // namespace mlsreg
