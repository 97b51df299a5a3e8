// TargetStore: the on-disk copy of uploaded target clouds, so that an evicted target or a
// restarted server loses nothing. Layout under the data directory:
//   targets/<id>.ply   the cloud as uploaded (binary PLY, doubles: bit-exact round trip)
//   targets/<id>.json  what the server knew about it (point count, d, memory, viewpoint)
//   tmp/               files being written; moved into targets/ by rename(), cleared at start
// A target exists on disk iff its .ply exists. Ids are validated ([A-Za-z0-9._-], no leading
// '.') before they get here, so they are safe file names; files in targets/ whose names are not
// valid ids (put there by hand) are ignored.
//
// Durability: both files are fsync'ed before they are renamed into place and the directory is
// fsync'ed after, so a target whose upload succeeded survives a power loss (docs/service.md).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg::server {

// What GetTarget/ListTargets report for a target that is not in memory.
struct StoredTargetMeta {
  std::uint64_t point_count = 0;
  std::uint64_t memory_bytes = 0;  // when it was last resident
  double sampling_distance = 0.0;
  double build_seconds = 0.0;
  double noise_sigma_d = 0.0;                   // Target::noise(); 0 in files of older versions
  std::optional<Vec3> viewpoint;                // PLY has no place for it
  std::optional<PinholeIntrinsics> intrinsics;  // organised scans (reverse calibration)
  std::string digest;                           // CloudDigest; empty in files of older versions
};

class TargetStore {
 public:
  // Creates the directories when missing and clears tmp/.
  static absl::StatusOr<std::unique_ptr<TargetStore>> Open(const std::string& data_dir);

  struct Entry {
    std::string id;
    StoredTargetMeta meta;  // zeros when the .json is missing or unreadable
  };
  // Every stored target.
  absl::StatusOr<std::vector<Entry>> List() const;

  // Writing is split so the caller can decide under its own lock whether the target is kept:
  // Stage writes the files into tmp/ (slow, no lock needed), Commit renames them into place
  // (atomic, cheap), Discard deletes them.
  struct Staged {
    std::string id;
    std::string cloud_path;
    std::string meta_path;
  };
  absl::StatusOr<Staged> Stage(const std::string& id, const PointCloud& cloud,
                               const StoredTargetMeta& meta);
  absl::Status Commit(const Staged& staged);
  void Discard(const Staged& staged);

  // The stored cloud with its viewpoint restored.
  absl::StatusOr<PointCloud> Load(const std::string& id) const;
  absl::Status Remove(const std::string& id);

 private:
  explicit TargetStore(std::string dir) : dir_(std::move(dir)) {}
  std::string CloudPath(const std::string& id) const;
  std::string MetaPath(const std::string& id) const;
  absl::StatusOr<StoredTargetMeta> ReadMeta(const std::string& id) const;

  std::string dir_;
  std::atomic<std::uint64_t> next_staging_id_{0};
};

}  // namespace mlsreg::server
