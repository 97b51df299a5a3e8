// Clouds a command reads and writes: --columns for files that may not name their columns, the
// reader's notes shown to the user, and output paths checked before any work is done.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/io/io.h"

namespace mlsreg::cli {

// --columns NAME,...: the columns of text (.xyz/.txt/.csv) and .npy clouds.
void AddColumnsFlag(CLI::App& cmd, std::vector<std::string>* columns);

// Whether `path` names a text or .npy cloud, whose columns --columns names.
bool TakesColumns(const std::string& path);
// InvalidArgument when `columns` are given but none of `paths` takes them.
absl::Status CheckColumnsApply(const std::vector<std::string>& columns,
                               const std::vector<std::string>& paths);

// Reads a cloud (with `columns` when it is a text or .npy file); the reader's notes (fields
// ignored, unnamed columns read from the data) and, when the file has normals, that they are not
// used go to stderr as "mlsreg COMMAND: note: ...".
absl::StatusOr<PointCloud> ReadCloudNoting(std::string_view command, const std::string& path,
                                           const std::vector<std::string>& columns = {});

// OK when `path` can be written as far as can be told without writing it: its directory exists
// and is one the user may write in, and `path` is not a directory. InvalidArgument naming
// `flag` otherwise; checked before a command starts its work.
absl::Status CheckWritable(std::string_view flag, const std::string& path);
// The same for a cloud, whose extension must name a format mlsreg writes (.ply, .pcd,
// .xyz/.txt/.csv, .npy).
absl::Status CheckCloudOutput(std::string_view flag, const std::string& path);

}  // namespace mlsreg::cli
