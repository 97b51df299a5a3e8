// A directory under the system's temporary path, removed with everything in it when the object
// goes (the embedded Python scripts' files, the shards of `eval --dask`).
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace mlsreg::cli {

class TemporaryDirectory {
 public:
  // UNAVAILABLE naming `what` when it cannot be made.
  static absl::StatusOr<TemporaryDirectory> Create(std::string_view prefix, std::string_view what) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / (std::string(prefix) + "-XXXXXX")).string();
    if (mkdtemp(pattern.data()) == nullptr) {
      return absl::UnavailableError(std::string(what) + ": cannot create a temporary directory");
    }
    return TemporaryDirectory(pattern);
  }
  TemporaryDirectory(TemporaryDirectory&& other) noexcept : path_(std::move(other.path_)) {
    other.path_.clear();
  }
  TemporaryDirectory& operator=(TemporaryDirectory&&) = delete;
  ~TemporaryDirectory() {
    std::error_code ignored;
    if (!path_.empty()) std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  explicit TemporaryDirectory(std::filesystem::path path) : path_(std::move(path)) {}
  std::filesystem::path path_;
};

}  // namespace mlsreg::cli
