#include "cli/cloud_files.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include "absl/strings/str_cat.h"

namespace mlsreg::cli {

void AddColumnsFlag(CLI::App& cmd, std::vector<std::string>* columns) {
  cmd.add_option("--columns", *columns,
                 "the columns of text (.xyz/.txt/.csv) and .npy clouds, e.g. x,y,z,r,g,b or "
                 "x,y,z,intensity: x y z, nx ny nz, r g b (0-255); other names are read and "
                 "ignored. Default: the file's header line, or from the column count (6 unnamed "
                 "columns are normals when every row is a unit vector, colours when every value "
                 "is an integer 0-255, else refused)")
      ->delimiter(',');
}

bool TakesColumns(const std::string& path) {
  const absl::StatusOr<CloudFormat> format = CloudFormatOfPath(path);
  return format.ok() && (*format == CloudFormat::kXyz || *format == CloudFormat::kNpy);
}

absl::Status CheckColumnsApply(const std::vector<std::string>& columns,
                               const std::vector<std::string>& paths) {
  if (columns.empty()) return absl::OkStatus();
  for (const std::string& path : paths) {
    if (TakesColumns(path)) return absl::OkStatus();
  }
  return absl::InvalidArgumentError(
      "--columns names the columns of text (.xyz/.txt/.csv) and .npy clouds, and no cloud read "
      "here is one (PLY and PCD headers name their fields)");
}

absl::StatusOr<PointCloud> ReadCloudNoting(std::string_view command, const std::string& path,
                                           const std::vector<std::string>& columns) {
  ReadOptions options;
  if (TakesColumns(path)) options.columns = columns;
  absl::StatusOr<CloudFile> file = ReadCloudFile(path, options);
  if (!file.ok()) return file.status();
  const std::string prefix = absl::StrCat("mlsreg ", std::string(command), ": note: ");
  for (const std::string& note : file->notes) {
    std::fprintf(stderr, "%s%s\n", prefix.c_str(), note.c_str());
  }
  if (file->cloud.has_normals()) {
    std::fprintf(stderr,
                 "%s%s: its normals are not used: mlsreg estimates normals from the points\n",
                 prefix.c_str(), path.c_str());
  }
  return std::move(file->cloud);
}

absl::Status CheckWritable(std::string_view flag, const std::string& path) {
  namespace fs = std::filesystem;
  const auto bad = [&](const std::string& why) {
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(flag), ": cannot write '", path, "': ", why));
  };
  if (path.empty()) return bad("the path is empty");
  std::error_code error;
  const fs::path file(path);
  if (fs::is_directory(file, error)) return bad("it is a directory");
  const fs::path dir = file.has_parent_path() ? file.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, error)) {
    return bad(absl::StrCat("the directory '", dir.string(), "' does not exist"));
  }
  if (access(dir.c_str(), W_OK | X_OK) != 0) {
    return bad(absl::StrCat("the directory '", dir.string(), "' is not writable"));
  }
  if (fs::exists(file, error) && access(path.c_str(), W_OK) != 0) {
    return bad("the file exists and is not writable");
  }
  return absl::OkStatus();
}

absl::Status CheckCloudOutput(std::string_view flag, const std::string& path) {
  if (absl::StatusOr<CloudFormat> format = CloudFormatOfPath(path); !format.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(flag), ": ", std::string(format.status().message())));
  }
  return CheckWritable(flag, path);
}

}  // namespace mlsreg::cli
