// Manifest: a CSV list of registration problems (the format of shared data sets' pairs.csv).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/transform.h"

namespace mlsreg {

// One row: `id,source,target[,gt][,init]` plus any extra columns, which are kept verbatim.
// (Not the registration's own RegistrationProblem, lib/src/registration/method_runners.h.)
struct ManifestProblem {
  std::string id;
  std::string source_path;  // resolved against the manifest's folder
  std::string target_path;
  std::optional<Matrix4> ground_truth;  // source -> target
  std::optional<Matrix4> initial;
  std::vector<std::pair<std::string, std::string>> extra;  // (column, value) in file order
};

struct Manifest {
  std::vector<std::string> extra_columns;
  std::vector<ManifestProblem> problems;
};

// Parses CSV text (RFC 4180 quoting; header required; columns id, source, target mandatory; gt
// and init optional, each one field of 16 numbers). Relative paths are resolved against
// `base_dir`. Errors name the line and column.
absl::StatusOr<Manifest> ParseManifest(std::string_view csv, const std::string& base_dir);
absl::StatusOr<Manifest> ReadManifest(const std::string& path);

// Splits one CSV line into fields (RFC 4180 quotes, no embedded newlines).
absl::StatusOr<std::vector<std::string>> SplitCsvLine(std::string_view line);

// Quotes a field for CSV output when it needs it.
std::string CsvField(std::string_view value);

}  // namespace mlsreg
