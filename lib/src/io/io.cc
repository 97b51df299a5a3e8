// Reading and writing point-cloud files: the format is chosen by the file's extension, the bytes
// are read or written whole, and io_ply.cc / io_pcd.cc / io_xyz.cc do the parsing and formatting.

#include "mlsreg/io/io.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <memory>
#include <string>
#include <system_error>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "io_internal.h"
#include "mlsreg/io/intrinsics_sidecar.h"

namespace mlsreg {
namespace {

using io_internal::LowerCaseExtension;

enum class FileFormat { kPly, kPcd, kXyz, kNpy };

absl::StatusOr<FileFormat> FormatOfPath(const std::string& path) {
  const std::string extension = LowerCaseExtension(path);
  if (extension == ".ply") return FileFormat::kPly;
  if (extension == ".pcd") return FileFormat::kPcd;
  if (extension == ".xyz" || extension == ".txt" || extension == ".csv") return FileFormat::kXyz;
  if (extension == ".npy") return FileFormat::kNpy;
  constexpr const char* kExpected = "expected .ply, .pcd, .xyz, .txt, .csv or .npy";
  if (extension.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("'", path, "' has no file extension; ", kExpected));
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown point-cloud file extension '", extension,
                                                 "' in '", path, "'; ", kExpected));
}

// NotFound when the file or a directory on its path does not exist, Unavailable otherwise.
absl::Status FileError(int error, const char* action, const std::string& path) {
  const std::string message =
      absl::StrCat("cannot ", action, " '", path, "': ", std::generic_category().message(error));
  if (error == ENOENT || error == ENOTDIR) return absl::NotFoundError(message);
  return absl::UnavailableError(message);
}

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

namespace io_internal {

// The extension of the last path component, lower-cased, with its dot (".ply"); empty if none.
std::string LowerCaseExtension(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::size_t name_start = slash == std::string::npos ? 0 : slash + 1;
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || dot <= name_start) return "";
  return absl::AsciiStrToLower(path.substr(dot));
}

}  // namespace io_internal

absl::StatusOr<std::string> ReadFileBytes(const std::string& path) {
  errno = 0;
  FilePtr file(std::fopen(path.c_str(), "rb"));
  if (file == nullptr) return FileError(errno, "open", path);
  std::string bytes;
  char buffer[1 << 16];
  std::size_t read = 0;
  while ((read = std::fread(buffer, 1, sizeof(buffer), file.get())) > 0) bytes.append(buffer, read);
  if (std::ferror(file.get())) return FileError(errno, "read", path);
  return bytes;
}

namespace {

absl::Status WriteFileBytes(const std::string& path, const std::string& bytes) {
  errno = 0;
  FilePtr file(std::fopen(path.c_str(), "wb"));
  if (file == nullptr) return FileError(errno, "create", path);
  if (std::fwrite(bytes.data(), 1, bytes.size(), file.get()) != bytes.size()) {
    return FileError(errno, "write", path);
  }
  if (std::fclose(file.release()) != 0) return FileError(errno, "write", path);
  return absl::OkStatus();
}

absl::StatusOr<PointCloud> Parse(FileFormat format, std::string_view bytes) {
  switch (format) {
    case FileFormat::kPly:
      return ParsePly(bytes);
    case FileFormat::kPcd:
      return ParsePcd(bytes);
    case FileFormat::kXyz:
      return ParseXyz(bytes);
    case FileFormat::kNpy:
      return ParseNpy(bytes);
  }
  return absl::InternalError("unknown file format");
}

std::string Serialize(const PointCloud& cloud, FileFormat format, const WriteOptions& options) {
  switch (format) {
    case FileFormat::kPly:
      return SerializePly(cloud, options.ply);
    case FileFormat::kPcd:
      return SerializePcd(cloud, options.pcd);
    case FileFormat::kXyz:
      return SerializeXyz(cloud);
    case FileFormat::kNpy:
      return SerializeNpy(cloud);
  }
  return "";
}

}  // namespace

absl::StatusOr<PointCloud> ReadPointCloud(const std::string& path) {
  const absl::StatusOr<FileFormat> format = FormatOfPath(path);
  if (!format.ok()) return format.status();
  const absl::StatusOr<std::string> bytes = ReadFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  absl::StatusOr<PointCloud> cloud = Parse(*format, *bytes);
  if (!cloud.ok()) {
    return absl::Status(cloud.status().code(), absl::StrCat(path, ": ", cloud.status().message()));
  }
  // An organised scan's pinhole intrinsics travel in a sidecar file (intrinsics_sidecar.h).
  absl::StatusOr<PinholeIntrinsics> intrinsics = ReadIntrinsicsSidecar(path);
  if (intrinsics.ok()) {
    cloud->intrinsics = *intrinsics;
  } else if (intrinsics.status().code() != absl::StatusCode::kNotFound) {
    return intrinsics.status();
  }
  return cloud;
}

absl::Status WritePlyWithAttributes(const PointCloud& cloud, const PointAttributes& attributes,
                                    const std::string& path) {
  const auto bad = [&](const std::string& why) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write '", path, "': ", why));
  };
  if (absl::Status valid = ValidatePointCloud(cloud, 1); !valid.ok()) {
    return bad(std::string(valid.message()));
  }
  if (!attributes.colors.empty() && attributes.colors.size() != cloud.size()) {
    return bad("one colour per point is needed");
  }
  static constexpr std::string_view kTaken[] = {"x",  "y",   "z",     "nx",  "ny",
                                                "nz", "red", "green", "blue"};
  for (const auto& [name, values] : attributes.scalars) {
    const bool word = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
    if (!word || std::find(std::begin(kTaken), std::end(kTaken), name) != std::end(kTaken)) {
      return bad(absl::StrCat("scalar name '", name, "' is not a free [A-Za-z0-9_]+ name"));
    }
    if (values.size() != cloud.size()) {
      return bad(absl::StrCat("scalar '", name, "' needs one value per point"));
    }
  }
  const bool normals = io_internal::WritesNormals(cloud);
  std::string out = absl::StrCat(
      "ply\nformat binary_little_endian 1.0\ncomment written by mlsreg\nelement vertex ",
      cloud.size(), "\nproperty double x\nproperty double y\nproperty double z\n");
  if (normals) out += "property double nx\nproperty double ny\nproperty double nz\n";
  for (const auto& [name, values] : attributes.scalars) {
    absl::StrAppend(&out, "property float ", name, "\n");
  }
  if (!attributes.colors.empty()) {
    out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  }
  out += "end_header\n";
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      io_internal::AppendDoubleBinary(cloud.points[i][k], std::endian::little, &out);
    }
    for (int k = 0; normals && k < 3; ++k) {
      io_internal::AppendDoubleBinary(cloud.normals[i][k], std::endian::little, &out);
    }
    for (const auto& [name, values] : attributes.scalars) {
      const std::uint32_t bits = std::bit_cast<std::uint32_t>(values[i]);
      for (int b = 0; b < 4; ++b) out += static_cast<char>((bits >> (8 * b)) & 0xff);
    }
    if (!attributes.colors.empty()) {
      for (std::uint8_t c : attributes.colors[i]) out += static_cast<char>(c);
    }
  }
  return WriteFileBytes(path, out);
}

absl::Status WritePointCloud(const PointCloud& cloud, const std::string& path,
                             const WriteOptions& options) {
  const absl::StatusOr<FileFormat> format = FormatOfPath(path);
  if (!format.ok()) return format.status();
  if (absl::Status valid = ValidatePointCloud(cloud, 1); !valid.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write '", path, "': ", valid.message()));
  }
  return WriteFileBytes(path, Serialize(cloud, *format, options));
}

}  // namespace mlsreg
