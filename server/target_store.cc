#include "server/target_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "mlsreg/io/io.h"
#include "nlohmann/json.hpp"
#include "server/ids.h"
#include "server/log.h"
#include "server/server_config.h"

namespace mlsreg::server {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kTargetsDir = "targets";
constexpr const char* kTmpDir = "tmp";

absl::Status IoError(const std::string& what, const std::string& path, const std::error_code& ec) {
  return absl::UnavailableError(absl::StrCat(what, " '", path, "': ", ec.message()));
}

// fsync of a file or a directory (O_RDONLY works for both on Linux).
absl::Status Sync(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    return absl::UnavailableError(
        absl::StrCat("cannot open '", path, "' to sync it: ", std::strerror(errno)));
  }
  const int rc = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (rc != 0) {
    return absl::UnavailableError(absl::StrCat("fsync '", path, "': ", std::strerror(error)));
  }
  return absl::OkStatus();
}

Json MetaToJson(const StoredTargetMeta& meta) {
  Json j = {{"point_count", meta.point_count},
            {"memory_bytes", meta.memory_bytes},
            {"sampling_distance", meta.sampling_distance},
            {"build_seconds", meta.build_seconds},
            {"noise_sigma_d", meta.noise_sigma_d}};
  if (!meta.digest.empty()) j["content_digest"] = meta.digest;
  if (meta.viewpoint) {
    j["viewpoint"] = {meta.viewpoint->x(), meta.viewpoint->y(), meta.viewpoint->z()};
  }
  if (meta.intrinsics) {
    const PinholeIntrinsics& k = *meta.intrinsics;
    j["intrinsics"] = {{"width", k.width}, {"height", k.height}, {"fx", k.fx},
                       {"fy", k.fy},       {"cx", k.cx},         {"cy", k.cy}};
  }
  return j;
}

std::optional<StoredTargetMeta> MetaFromJson(const Json& j) {
  StoredTargetMeta meta;
  if (!j.is_object()) return std::nullopt;
  auto number = [&](const char* key) { return j.contains(key) && j[key].is_number(); };
  if (!number("point_count") || !number("memory_bytes") || !number("sampling_distance") ||
      !number("build_seconds")) {
    return std::nullopt;
  }
  meta.point_count = j["point_count"].get<std::uint64_t>();
  meta.memory_bytes = j["memory_bytes"].get<std::uint64_t>();
  meta.sampling_distance = j["sampling_distance"].get<double>();
  meta.build_seconds = j["build_seconds"].get<double>();
  if (number("noise_sigma_d")) meta.noise_sigma_d = j["noise_sigma_d"].get<double>();
  if (j.contains("content_digest")) {
    if (!j["content_digest"].is_string()) return std::nullopt;
    meta.digest = j["content_digest"].get<std::string>();
  }
  if (j.contains("viewpoint")) {
    const Json& v = j["viewpoint"];
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
        !v[2].is_number()) {
      return std::nullopt;
    }
    meta.viewpoint = Vec3(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  }
  if (j.contains("intrinsics")) {
    const Json& k = j["intrinsics"];
    for (const char* key : {"width", "height", "fx", "fy", "cx", "cy"}) {
      if (!k.is_object() || !k.contains(key) || !k[key].is_number()) return std::nullopt;
    }
    meta.intrinsics =
        PinholeIntrinsics{k["width"].get<int>(), k["height"].get<int>(), k["fx"].get<double>(),
                          k["fy"].get<double>(), k["cx"].get<double>(),  k["cy"].get<double>()};
  }
  return meta;
}

}  // namespace

absl::StatusOr<std::unique_ptr<TargetStore>> TargetStore::Open(const std::string& data_dir) {
  std::error_code ec;
  for (const char* sub : {kTargetsDir, kTmpDir}) {
    const fs::path dir = fs::path(data_dir) / sub;
    fs::create_directories(dir, ec);
    if (ec) return IoError("cannot create data directory", dir.string(), ec);
  }
  // Leftovers of writes interrupted by a crash: never committed, so never visible.
  const fs::path tmp = fs::path(data_dir) / kTmpDir;
  for (const auto& entry : fs::directory_iterator(tmp, ec)) fs::remove_all(entry.path(), ec);
  return std::unique_ptr<TargetStore>(new TargetStore(data_dir));
}

std::string TargetStore::CloudPath(const std::string& id) const {
  return (fs::path(dir_) / kTargetsDir / (id + ".ply")).string();
}

std::string TargetStore::MetaPath(const std::string& id) const {
  return (fs::path(dir_) / kTargetsDir / (id + ".json")).string();
}

absl::StatusOr<StoredTargetMeta> TargetStore::ReadMeta(const std::string& id) const {
  auto text = ReadTextFile(MetaPath(id), "target metadata");
  if (!text.ok()) return text.status();
  const Json j = Json::parse(*text, nullptr, /*allow_exceptions=*/false);
  std::optional<StoredTargetMeta> meta = MetaFromJson(j);
  if (!meta) return absl::DataLossError(absl::StrCat("corrupt metadata '", MetaPath(id), "'"));
  return *meta;
}

absl::StatusOr<std::vector<TargetStore::Entry>> TargetStore::List() const {
  std::vector<Entry> entries;
  std::error_code ec;
  const fs::path dir = fs::path(dir_) / kTargetsDir;
  for (const auto& file : fs::directory_iterator(dir, ec)) {
    if (!file.is_regular_file() || file.path().extension() != ".ply") continue;
    Entry entry;
    entry.id = file.path().stem().string();
    if (!ValidateTargetId(entry.id, "stored target").ok()) {
      LogLine(absl::StrCat("target store: ignoring '", file.path().string(),
                           "': its name is not a valid target id"));
      continue;
    }
    if (auto meta = ReadMeta(entry.id); meta.ok()) entry.meta = *meta;
    entries.push_back(std::move(entry));
  }
  if (ec) return IoError("cannot list", dir.string(), ec);
  return entries;
}

absl::StatusOr<TargetStore::Staged> TargetStore::Stage(const std::string& id,
                                                       const PointCloud& cloud,
                                                       const StoredTargetMeta& meta) {
  // Unique names, so concurrent uploads of the same id never write the same file.
  const std::string stem =
      (fs::path(dir_) / kTmpDir / absl::StrCat(id, ".", next_staging_id_.fetch_add(1))).string();
  Staged staged{id, stem + ".ply", stem + ".json"};
  if (absl::Status s = WritePointCloud(cloud, staged.cloud_path); !s.ok()) {
    Discard(staged);
    return s;
  }
  std::ofstream out(staged.meta_path, std::ios::binary | std::ios::trunc);
  out << MetaToJson(meta).dump(2) << "\n";
  out.close();
  if (!out) {
    Discard(staged);
    return absl::UnavailableError(absl::StrCat("cannot write '", staged.meta_path, "'"));
  }
  for (const std::string& path : {staged.cloud_path, staged.meta_path}) {
    if (absl::Status s = Sync(path); !s.ok()) {
      Discard(staged);
      return s;
    }
  }
  return staged;
}

absl::Status TargetStore::Commit(const Staged& staged) {
  std::error_code ec;
  // Metadata first: the .ply appearing is what makes the target exist.
  fs::rename(staged.meta_path, MetaPath(staged.id), ec);
  if (ec) return IoError("cannot move into place", staged.meta_path, ec);
  fs::rename(staged.cloud_path, CloudPath(staged.id), ec);
  if (ec) return IoError("cannot move into place", staged.cloud_path, ec);
  // The renames are durable once the directory is.
  return Sync((fs::path(dir_) / kTargetsDir).string());
}

void TargetStore::Discard(const Staged& staged) {
  std::error_code ec;
  fs::remove(staged.cloud_path, ec);
  fs::remove(staged.meta_path, ec);
}

absl::StatusOr<PointCloud> TargetStore::Load(const std::string& id) const {
  auto cloud = ReadPointCloud(CloudPath(id));
  if (!cloud.ok()) return cloud.status();
  if (auto meta = ReadMeta(id); meta.ok()) {
    cloud->viewpoint = meta->viewpoint;
    cloud->intrinsics = meta->intrinsics;
  }
  return cloud;
}

absl::Status TargetStore::Remove(const std::string& id) {
  std::error_code ec;
  fs::remove(CloudPath(id), ec);  // the target is gone from here on
  if (ec) return IoError("cannot remove", CloudPath(id), ec);
  fs::remove(MetaPath(id), ec);
  return Sync((fs::path(dir_) / kTargetsDir).string());
}

}  // namespace mlsreg::server
