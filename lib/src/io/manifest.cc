#include "mlsreg/io/manifest.h"

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "mlsreg/io/io.h"

namespace mlsreg {

absl::StatusOr<std::vector<std::string>> SplitCsvLine(std::string_view line) {
  std::vector<std::string> fields;
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"' && field.empty()) {
      quoted = true;
    } else if (c == ',') {
      fields.push_back(std::move(field));
      field.clear();
    } else if (c != '\r') {
      field += c;
    }
  }
  if (quoted) return absl::InvalidArgumentError("unterminated quoted field");
  fields.push_back(std::move(field));
  return fields;
}

std::string CsvField(std::string_view value) {
  if (value.find_first_of(",\"\n") == std::string_view::npos) return std::string(value);
  std::string out = "\"";
  for (char c : value) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

absl::StatusOr<Manifest> ParseManifest(std::string_view csv, const std::string& base_dir) {
  std::istringstream in{std::string(csv)};
  std::string line;
  int line_number = 0;
  std::vector<std::string> header;
  std::map<std::string, std::size_t> column;
  Manifest manifest;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    auto fields = SplitCsvLine(line);
    if (!fields.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("manifest line ", line_number, ": ", fields.status().message()));
    }
    if (header.empty()) {
      header = *fields;
      for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
      for (const char* required : {"id", "source", "target"}) {
        if (!column.count(required)) {
          return absl::InvalidArgumentError(absl::StrCat("manifest header (line ", line_number,
                                                         ") lacks the column '", required, "'"));
        }
      }
      for (const std::string& name : header) {
        if (name != "id" && name != "source" && name != "target" && name != "gt" &&
            name != "init") {
          manifest.extra_columns.push_back(name);
        }
      }
      continue;
    }
    if (fields->size() != header.size()) {
      return absl::InvalidArgumentError(absl::StrCat("manifest line ", line_number, " has ",
                                                     fields->size(), " fields; the header has ",
                                                     header.size()));
    }
    auto field = [&](const std::string& name) -> const std::string& {
      return (*fields)[column.at(name)];
    };
    auto resolve = [&](const std::string& path) {
      const std::filesystem::path p(path);
      return p.is_absolute() ? path : (std::filesystem::path(base_dir) / p).string();
    };
    ManifestProblem problem;
    problem.id = field("id");
    problem.source_path = resolve(field("source"));
    problem.target_path = resolve(field("target"));
    for (const char* name : {"gt", "init"}) {
      if (!column.count(name) || field(name).empty()) continue;
      auto m = ParseTransform(field(name),
                              absl::StrCat("manifest line ", line_number, " column ", name));
      if (!m.ok()) return m.status();
      (std::string(name) == "gt" ? problem.ground_truth : problem.initial) = *m;
    }
    for (const std::string& name : manifest.extra_columns) {
      problem.extra.emplace_back(name, field(name));
    }
    manifest.problems.push_back(std::move(problem));
  }
  if (header.empty()) return absl::InvalidArgumentError("manifest is empty (no header)");
  return manifest;
}

absl::StatusOr<Manifest> ReadManifest(const std::string& path) {
  absl::StatusOr<std::string> text = ReadFileBytes(path);
  if (!text.ok()) {
    return absl::Status(text.status().code(),
                        absl::StrCat("cannot read manifest: ", text.status().message()));
  }
  return ParseManifest(*text, std::filesystem::path(path).parent_path().string());
}

}  // namespace mlsreg
