// Reading and writing point-cloud files: the format is chosen by the file's extension, the bytes
// are read or written whole, and io_ply.cc / io_pcd.cc / io_xyz.cc / io_npy.cc do the parsing
// and formatting.

#include "mlsreg/io/io.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <filesystem>
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

absl::StatusOr<CloudFormat> CloudFormatOfPath(const std::string& path) {
  const std::string extension = LowerCaseExtension(path);
  if (extension == ".ply") return CloudFormat::kPly;
  if (extension == ".pcd") return CloudFormat::kPcd;
  if (extension == ".xyz" || extension == ".txt" || extension == ".csv") return CloudFormat::kXyz;
  if (extension == ".npy") return CloudFormat::kNpy;
  constexpr const char* kExpected = "expected .ply, .pcd, .xyz, .txt, .csv or .npy";
  if (extension.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("'", path, "' has no file extension; ", kExpected));
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown point-cloud file extension '", extension,
                                                 "' in '", path, "'; ", kExpected));
}

absl::StatusOr<std::string> ReadFileBytes(const std::string& path) {
  errno = 0;
  FilePtr file(std::fopen(path.c_str(), "rb"));
  if (file == nullptr) return FileError(errno, "open", path);
  std::string bytes;
  // Room for the whole file at once (its size is only a hint: it may change while we read), so
  // that the string is not reallocated and copied as it grows.
  std::error_code size_error;
  const std::uintmax_t size = std::filesystem::file_size(path, size_error);
  if (!size_error && size <= bytes.max_size()) bytes.reserve(static_cast<std::size_t>(size));
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

// `scalars` null: the plain cloud (WritePointCloud), which an NPY file holds without colours.
std::string Serialize(const PointCloud& cloud, CloudFormat format, const WriteOptions& options,
                      const io_internal::ScalarFields* scalars, const std::string& path) {
  const io_internal::ScalarFields none;
  const io_internal::ScalarFields& fields = scalars != nullptr ? *scalars : none;
  switch (format) {
    case CloudFormat::kPly:
      return io_internal::PlyBytes(cloud, options.ply, fields);
    case CloudFormat::kPcd:
      return io_internal::PcdBytes(cloud, options.pcd, fields);
    case CloudFormat::kXyz:
      return io_internal::XyzText(cloud, fields, LowerCaseExtension(path) == ".csv" ? ',' : ' ');
    case CloudFormat::kNpy:
      return io_internal::NpyBytes(cloud, fields, scalars != nullptr);
  }
  return "";
}

}  // namespace

absl::StatusOr<CloudFile> ParseCloudFile(CloudFormat format, std::string_view bytes,
                                         const ReadOptions& options) {
  if (!options.columns.empty() && (format == CloudFormat::kPly || format == CloudFormat::kPcd)) {
    return absl::InvalidArgumentError(
        "columns are named for a PLY or PCD file, whose header names its fields; they apply to "
        "text (.xyz, .txt, .csv) and .npy files");
  }
  switch (format) {
    case CloudFormat::kPly:
      return io_internal::ParsePlyFile(bytes);
    case CloudFormat::kPcd:
      return io_internal::ParsePcdFile(bytes);
    case CloudFormat::kXyz:
      return io_internal::ParseXyzFile(bytes, options);
    case CloudFormat::kNpy:
      return io_internal::ParseNpyFile(bytes, options);
  }
  return absl::InternalError("unknown file format");
}

absl::StatusOr<CloudFile> ReadCloudFile(const std::string& path, const ReadOptions& options) {
  const absl::StatusOr<CloudFormat> format = CloudFormatOfPath(path);
  if (!format.ok()) return format.status();
  const absl::StatusOr<std::string> bytes = ReadFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  absl::StatusOr<CloudFile> file = ParseCloudFile(*format, *bytes, options);
  if (!file.ok()) {
    return absl::Status(file.status().code(), absl::StrCat(path, ": ", file.status().message()));
  }
  for (std::string& note : file->notes) note = absl::StrCat(path, ": ", note);
  // An organised scan's pinhole intrinsics travel in a sidecar file (intrinsics_sidecar.h).
  absl::StatusOr<PinholeIntrinsics> intrinsics = ReadIntrinsicsSidecar(path);
  if (intrinsics.ok()) {
    file->cloud.intrinsics = *intrinsics;
  } else if (intrinsics.status().code() != absl::StatusCode::kNotFound) {
    return intrinsics.status();
  }
  return file;
}

absl::StatusOr<PointCloud> ReadPointCloud(const std::string& path) {
  absl::StatusOr<CloudFile> file = ReadCloudFile(path);
  if (!file.ok()) return file.status();
  return std::move(file->cloud);
}

absl::Status WriteCloudWithAttributes(const PointCloud& cloud, const PointAttributes& attributes,
                                      const std::string& path) {
  const auto bad = [&](const std::string& why) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write '", path, "': ", why));
  };
  const absl::StatusOr<CloudFormat> format = CloudFormatOfPath(path);
  if (!format.ok()) return format.status();
  if (absl::Status valid = ValidatePointCloud(cloud, 1); !valid.ok()) {
    return bad(std::string(valid.message()));
  }
  static constexpr std::string_view kTaken[] = {"x",     "y",    "z", "nx", "ny", "nz", "red",
                                                "green", "blue", "r", "g",  "b",  "rgb"};
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
  return WriteFileBytes(path, Serialize(cloud, *format, {}, &attributes.scalars, path));
}

absl::Status WritePointCloud(const PointCloud& cloud, const std::string& path,
                             const WriteOptions& options) {
  const absl::StatusOr<CloudFormat> format = CloudFormatOfPath(path);
  if (!format.ok()) return format.status();
  if (absl::Status valid = ValidatePointCloud(cloud, 1); !valid.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("cannot write '", path, "': ", valid.message()));
  }
  return WriteFileBytes(path, Serialize(cloud, *format, options, nullptr, path));
}

}  // namespace mlsreg
