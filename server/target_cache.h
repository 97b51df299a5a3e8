// TargetCache: the targets this server knows, by id. Built targets (kd-tree, normals, curvature)
// stay resident under a byte budget; the least recently used idle ones are evicted to make room.
// With a TargetStore every target is also on disk, so eviction only drops the memory: the next
// registration reloads and rebuilds it (state STORED until then). Without one, eviction forgets
// the target.
//
// Thread-safe behind one mutex, which is never held while a Target is built or a file written.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/geometry/target_info.h"
#include "server/target_store.h"

namespace mlsreg::server {

struct CacheCounters {
  // Held by resident targets, and by deleted ones that registrations still use.
  std::uint64_t bytes = 0;
  std::uint64_t budget_bytes = 0;
  int entries = 0;              // known targets, resident or stored
  std::uint64_t hits = 0;       // lookups that found the target resident
  std::uint64_t misses = 0;     // lookups that had to reload it from the store
  std::uint64_t evictions = 0;  // targets dropped from memory to make room
  std::uint64_t builds = 0;     // targets built (uploads and reloads)
  double build_seconds = 0.0;   // their wall time, in total
};

class TargetCache {
 public:
  // `store` may be null (memory only). Indexes the targets already in the store as STORED.
  // `build_threads`: TargetOptions::threads of every build.
  static absl::StatusOr<std::unique_ptr<TargetCache>> Open(std::uint64_t budget_bytes,
                                                           std::unique_ptr<TargetStore> store,
                                                           int build_threads = 1);

  // What an upload of `id` with content `digest` meets: the existing target when it holds the
  // same content (the upload is done: creation is idempotent), nullopt when the id is free,
  // ALREADY_EXISTS when the id holds other content. An empty `digest` (not known yet) only
  // tells a free id from a taken one.
  absl::StatusOr<std::optional<TargetInfo>> Existing(std::string_view id,
                                                     std::string_view digest) const;

  // Cheap checks before an upload is read: Existing(id, digest), and RESOURCE_EXHAUSTED (for
  // good) when `min_bytes` (a lower bound of the built target's size) can never fit.
  absl::StatusOr<std::optional<TargetInfo>> CheckCanCreate(std::string_view id,
                                                           std::uint64_t min_bytes,
                                                           std::string_view digest) const;

  // Builds the target of an upload and adds it (Insert). The one loader: while a target builds,
  // its id is loading, and a concurrent Create or Acquire of that id waits for the build instead
  // of starting another, so each target builds once. RESOURCE_EXHAUSTED before the build when
  // its estimate (Target::EstimateBytes) cannot fit; INVALID_ARGUMENT "cloud: ..." when the cloud
  // cannot be built; CANCELLED when `should_stop` said stop.
  absl::StatusOr<TargetInfo> Create(const std::string& id, PointCloud cloud,
                                    const std::string& digest, const StopCheck& should_stop = {});

  // Adds a freshly built target with content `digest` (persisting it first when there is a
  // store), evicting idle targets when needed. When the id exists meanwhile: the stored target if
  // its content is the same, else ALREADY_EXISTS. RESOURCE_EXHAUSTED when it cannot fit even after
  // evicting every idle target (retry later), or can never fit (for good).
  absl::StatusOr<TargetInfo> Insert(const std::string& id, std::shared_ptr<const Target> target,
                                    const std::string& digest);

  // The resident target, or nullptr when it is known but only stored (Acquire loads it).
  // NOT_FOUND for an unknown id. Never blocks on a build.
  absl::StatusOr<std::shared_ptr<const Target>> Peek(std::string_view id);

  // The target, reloaded from the store and rebuilt when it is not resident (slow: call it on a
  // worker; the rebuild asks `should_stop`), through the one loader (see Create): concurrent
  // Acquires of a stored target rebuild it once. RESOURCE_EXHAUSTED before the rebuild when its
  // recorded size cannot fit; NOT_FOUND for an unknown id, CANCELLED when stopped.
  absl::StatusOr<std::shared_ptr<const Target>> Acquire(std::string_view id,
                                                        const StopCheck& should_stop = {});

  absl::StatusOr<TargetInfo> Info(std::string_view id) const;
  // Up to `limit` targets with id > `after`, sorted by id; `more` tells whether others follow.
  std::vector<TargetInfo> List(std::string_view after, std::size_t limit, bool* more) const;
  // Forgets the target and deletes its files. Registrations holding it finish normally; its
  // bytes stay counted until the last of them lets it go.
  absl::Status Erase(std::string_view id);

  void CountRegistration(std::string_view id);
  CacheCounters counters() const;

 private:
  struct Entry {
    std::shared_ptr<const Target> target;  // null when only stored
    StoredTargetMeta meta;
    std::uint64_t registrations = 0;
    std::uint64_t last_use = 0;  // LRU clock value
  };
  using Entries = std::map<std::string, Entry, std::less<>>;

  // Marks the id loading, first waiting while another build of it runs (polling
  // `should_stop`): CANCELLED when stopped meanwhile. `lock` holds mutex_, again on return.
  absl::Status WaitToLoadLocked(std::unique_lock<std::mutex>& lock, const std::string& id,
                                const StopCheck& should_stop);
  void FinishLoadingLocked(const std::string& id);
  // Target::Build, counted in builds_ and build_seconds_ (whatever its outcome).
  absl::StatusOr<std::shared_ptr<const Target>> TimedBuild(PointCloud cloud,
                                                           const StopCheck& should_stop);
  // Acquire's build: the stored cloud loaded, built and made resident.
  absl::StatusOr<std::shared_ptr<const Target>> ReloadAndInsert(const std::string& id,
                                                                const StopCheck& should_stop);
  static bool IsIdle(const Entry& e) { return e.target && e.target.use_count() == 1; }
  // Whether `bytes` could fit by evicting idle targets (nothing is evicted).
  absl::Status CheckFitLocked(std::uint64_t bytes, std::string_view for_id) const;

  TargetCache(std::uint64_t budget_bytes, std::unique_ptr<TargetStore> store, int build_threads)
      : budget_bytes_(budget_bytes), store_(std::move(store)), build_threads_(build_threads) {}

  // Evicts least recently used idle targets until `bytes` more fit; evicts nothing and returns
  // RESOURCE_EXHAUSTED when that is impossible. Requires mutex_.
  absl::Status MakeRoomLocked(std::uint64_t bytes, std::string_view for_id);
  TargetInfo InfoLocked(const std::string& id, const Entry& entry) const;
  absl::StatusOr<std::optional<TargetInfo>> ExistingLocked(std::string_view id,
                                                           std::string_view digest) const;
  // Stops counting deleted targets that nobody uses any more. Requires mutex_.
  void PruneRetiredLocked() const;
  static StoredTargetMeta MetaOf(const Target& target, const std::string& digest);

  const std::uint64_t budget_bytes_;
  const std::unique_ptr<TargetStore> store_;
  const int build_threads_;
  TargetOptions BuildOptions() const {
    TargetOptions options = TargetOptions::ForServing();
    options.threads = build_threads_;
    return options;
  }
  mutable std::mutex mutex_;
  Entries entries_;
  // Resident + retired bytes. Deleted targets that registrations held are counted in bytes_
  // until released; any reader may notice that (hence mutable).
  mutable std::uint64_t bytes_ = 0;
  mutable std::vector<std::pair<std::weak_ptr<const Target>, std::uint64_t>> retired_;
  // Ids whose target is being built (Create, Acquire): others wait on `loaded_`.
  std::set<std::string, std::less<>> loading_;
  std::condition_variable loaded_;
  std::uint64_t clock_ = 0;
  std::uint64_t hits_ = 0, misses_ = 0, evictions_ = 0, builds_ = 0;
  double build_seconds_ = 0.0;
};

}  // namespace mlsreg::server
