#include "server/target_cache.h"

#include <chrono>
#include <optional>

#include "absl/strings/str_cat.h"
#include "mlsreg/core/cloud_digest.h"
#include "server/log.h"
#include "server/retry_hint.h"

namespace mlsreg::server {
namespace {

absl::Status NotFound(std::string_view id) {
  return absl::NotFoundError(absl::StrCat("target '", std::string(id), "' not found"));
}

}  // namespace

absl::StatusOr<std::unique_ptr<TargetCache>> TargetCache::Open(std::uint64_t budget_bytes,
                                                               std::unique_ptr<TargetStore> store,
                                                               int build_threads) {
  std::unique_ptr<TargetCache> cache(
      new TargetCache(budget_bytes, std::move(store), std::max(1, build_threads)));
  if (cache->store_) {
    auto stored = cache->store_->List();
    if (!stored.ok()) return stored.status();
    for (TargetStore::Entry& e : *stored) {
      if (e.meta.digest.empty()) {  // stored by an older version: learn it once per start
        if (auto cloud = cache->store_->Load(e.id); cloud.ok()) {
          e.meta.digest = CloudDigest(*cloud);
        } else {
          LogLine(
              absl::StrCat("target store: '", e.id, "' unreadable: ", cloud.status().message()));
        }
      }
      cache->entries_[e.id].meta = e.meta;
    }
  }
  return cache;
}

StoredTargetMeta TargetCache::MetaOf(const Target& target, const std::string& digest) {
  StoredTargetMeta meta;
  meta.digest = digest;
  meta.point_count = target.cloud().size();
  meta.memory_bytes = target.MemoryBytes();
  meta.sampling_distance = target.sampling_distance();
  meta.build_seconds = target.build_seconds();
  meta.noise_sigma_d = target.noise().sigma_d;
  meta.viewpoint = target.cloud().viewpoint;
  meta.intrinsics = target.cloud().intrinsics;
  return meta;
}

TargetInfo TargetCache::InfoLocked(const std::string& id, const Entry& entry) const {
  TargetInfo info;
  info.id = id;
  info.state = entry.target ? TargetState::kReady : TargetState::kStored;
  info.point_count = entry.meta.point_count;
  info.memory_bytes = entry.meta.memory_bytes;
  info.sampling_distance = entry.meta.sampling_distance;
  info.build_seconds = entry.meta.build_seconds;
  info.noise_sigma_d = entry.meta.noise_sigma_d;
  info.registrations = entry.registrations;
  info.has_intrinsics = entry.meta.intrinsics.has_value();
  info.digest = entry.meta.digest;
  return info;
}

absl::StatusOr<std::optional<TargetInfo>> TargetCache::ExistingLocked(
    std::string_view id, std::string_view digest) const {
  const auto it = entries_.find(id);
  if (it == entries_.end()) return std::nullopt;
  if (digest.empty()) {
    return absl::AlreadyExistsError(absl::StrCat("target '", std::string(id), "' already exists"));
  }
  if (digest != it->second.meta.digest) {
    return absl::AlreadyExistsError(
        absl::StrCat("target '", std::string(id), "' already exists with other content (stored ",
                     it->second.meta.digest, ", this upload ", std::string(digest),
                     "); delete it first or use another id"));
  }
  return InfoLocked(it->first, it->second);
}

absl::StatusOr<std::optional<TargetInfo>> TargetCache::Existing(std::string_view id,
                                                                std::string_view digest) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return ExistingLocked(id, digest);
}

absl::StatusOr<std::optional<TargetInfo>> TargetCache::CheckCanCreate(
    std::string_view id, std::uint64_t min_bytes, std::string_view digest) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!digest.empty() || entries_.find(id) == entries_.end()) {
    auto existing = ExistingLocked(id, digest);
    if (!existing.ok() || existing->has_value()) return existing;
  }
  // A taken id without a declared digest: the data decides (Insert compares).
  if (min_bytes > budget_bytes_) {
    return Permanent(absl::ResourceExhaustedError(
        absl::StrCat("target '", std::string(id), "' needs at least ", min_bytes,
                     " bytes of cache but the budget is ", budget_bytes_, " bytes")));
  }
  return std::nullopt;
}

void TargetCache::PruneRetiredLocked() const {
  std::erase_if(retired_, [this](const auto& retired) {
    if (!retired.first.expired()) return false;
    bytes_ -= retired.second;
    return true;
  });
}

absl::Status TargetCache::CheckFitLocked(std::uint64_t bytes, std::string_view for_id) const {
  PruneRetiredLocked();
  if (bytes_ + bytes <= budget_bytes_) return absl::OkStatus();
  if (bytes > budget_bytes_) {
    return Permanent(absl::ResourceExhaustedError(
        absl::StrCat("target '", std::string(for_id), "' needs ", bytes,
                     " bytes of cache but the budget is ", budget_bytes_, " bytes")));
  }
  // Idle: only the cache holds it. Nobody can take a new reference without the mutex, so a
  // use_count of 1 cannot grow while we decide.
  std::uint64_t evictable = 0;
  for (const auto& [id, e] : entries_) {
    if (IsIdle(e)) evictable += e.meta.memory_bytes;
  }
  if (bytes_ - evictable + bytes > budget_bytes_) {
    return RetryLater(absl::ResourceExhaustedError(absl::StrCat(
                          "target cache full: '", std::string(for_id), "' needs ", bytes,
                          " bytes, ", bytes_ - evictable, " of the ", budget_bytes_,
                          "-byte budget are held by targets in use; retry later")),
                      std::chrono::milliseconds(1000));
  }
  return absl::OkStatus();
}

absl::Status TargetCache::MakeRoomLocked(std::uint64_t bytes, std::string_view for_id) {
  if (absl::Status s = CheckFitLocked(bytes, for_id); !s.ok()) return s;
  while (bytes_ + bytes > budget_bytes_) {
    auto victim = entries_.end();
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (IsIdle(it->second) &&
          (victim == entries_.end() || it->second.last_use < victim->second.last_use)) {
        victim = it;
      }
    }
    bytes_ -= victim->second.meta.memory_bytes;
    ++evictions_;
    if (store_) {
      victim->second.target.reset();  // still on disk: STORED
    } else {
      entries_.erase(victim);
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<TargetInfo> TargetCache::Insert(const std::string& id,
                                               std::shared_ptr<const Target> target,
                                               const std::string& digest) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto existing = ExistingLocked(id, digest);
    if (!existing.ok()) return existing.status();
    if (existing->has_value()) return **existing;  // the same content: nothing to store
  }
  const StoredTargetMeta meta = MetaOf(*target, digest);
  std::optional<TargetStore::Staged> staged;
  if (store_) {
    auto s = store_->Stage(id, target->cloud(), meta);
    if (!s.ok()) return s.status();
    staged = std::move(*s);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  auto fail = [&](absl::Status status) {
    if (staged) store_->Discard(*staged);
    return status;
  };
  // Created concurrently meanwhile: theirs stays, our staged files go.
  auto existing = ExistingLocked(id, digest);
  if (!existing.ok()) return fail(existing.status());
  if (existing->has_value()) {
    if (staged) store_->Discard(*staged);
    return **existing;
  }
  if (absl::Status s = MakeRoomLocked(meta.memory_bytes, id); !s.ok()) return fail(s);
  if (staged) {
    if (absl::Status s = store_->Commit(*staged); !s.ok()) return fail(s);
  }
  Entry& entry = entries_[id];
  entry.target = std::move(target);
  entry.meta = meta;
  entry.last_use = ++clock_;
  bytes_ += meta.memory_bytes;
  return InfoLocked(id, entry);
}

absl::StatusOr<std::shared_ptr<const Target>> TargetCache::Peek(std::string_view id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return NotFound(id);
  if (it->second.target) {
    ++hits_;
    it->second.last_use = ++clock_;
  }
  return it->second.target;
}

absl::Status TargetCache::WaitToLoadLocked(std::unique_lock<std::mutex>& lock,
                                           const std::string& id, const StopCheck& should_stop) {
  while (loading_.count(id)) {
    loaded_.wait_for(lock, std::chrono::milliseconds(50));
    if (should_stop && should_stop()) {
      return absl::CancelledError(
          absl::StrCat("stopped while target '", id, "' was being built by another request"));
    }
  }
  loading_.insert(id);
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<const Target>> TargetCache::TimedBuild(
    PointCloud cloud, const StopCheck& should_stop) {
  const auto start = std::chrono::steady_clock::now();
  auto built = Target::Build(std::move(cloud), BuildOptions(), should_stop);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::lock_guard<std::mutex> lock(mutex_);
  ++builds_;
  build_seconds_ += seconds;
  return built;
}

void TargetCache::FinishLoadingLocked(const std::string& id) {
  loading_.erase(id);
  loaded_.notify_all();
}

absl::StatusOr<TargetInfo> TargetCache::Create(const std::string& id, PointCloud cloud,
                                               const std::string& digest,
                                               const StopCheck& should_stop) {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (absl::Status s = WaitToLoadLocked(lock, id, should_stop); !s.ok()) return s;
    // A concurrent upload of the id may have finished while this one waited.
    auto existing = ExistingLocked(id, digest);
    absl::Status fit =
        existing.ok() && !existing->has_value()
            ? CheckFitLocked(
                  Target::EstimateBytes(cloud.size(), cloud.has_normals(), cloud.intrinsics), id)
            : absl::OkStatus();
    if (!existing.ok() || existing->has_value() || !fit.ok()) {
      FinishLoadingLocked(id);
      if (!existing.ok()) return existing.status();
      if (existing->has_value()) return **existing;
      return fit;
    }
  }
  absl::StatusOr<TargetInfo> result = [&]() -> absl::StatusOr<TargetInfo> {
    auto target = TimedBuild(std::move(cloud), should_stop);
    if (absl::IsCancelled(target.status())) return target.status();
    if (!target.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("cloud: cannot build the target: ", target.status().message()));
    }
    return Insert(id, *std::move(target), digest);
  }();
  std::lock_guard<std::mutex> lock(mutex_);
  FinishLoadingLocked(id);
  return result;
}

absl::StatusOr<std::shared_ptr<const Target>> TargetCache::Acquire(std::string_view id_view,
                                                                   const StopCheck& should_stop) {
  const std::string id(id_view);
  {
    std::unique_lock<std::mutex> lock(mutex_);
    auto it = entries_.find(id);
    if (it == entries_.end()) return NotFound(id);
    if (it->second.target) {
      ++hits_;
      it->second.last_use = ++clock_;
      return it->second.target;
    }
    if (!store_) return NotFound(id);  // unreachable: without a store evicted means gone
    ++misses_;
    if (absl::Status s = WaitToLoadLocked(lock, id, should_stop); !s.ok()) return s;
    // Another request may have rebuilt it (or deleted it) while this one waited.
    it = entries_.find(id);
    absl::Status fit = it != entries_.end() && !it->second.target
                           ? CheckFitLocked(it->second.meta.memory_bytes, id)
                           : absl::OkStatus();
    if (it == entries_.end() || it->second.target || !fit.ok()) {
      FinishLoadingLocked(id);
      if (it == entries_.end()) return NotFound(id);
      if (!fit.ok()) return fit;
      it->second.last_use = ++clock_;
      return it->second.target;
    }
  }
  // Reload outside the lock: reading and building take a while and other targets stay usable.
  absl::StatusOr<std::shared_ptr<const Target>> result = ReloadAndInsert(id, should_stop);
  std::lock_guard<std::mutex> lock(mutex_);
  FinishLoadingLocked(id);
  return result;
}

absl::StatusOr<std::shared_ptr<const Target>> TargetCache::ReloadAndInsert(
    const std::string& id, const StopCheck& should_stop) {
  auto cloud = store_->Load(id);
  if (!cloud.ok()) {
    if (absl::IsNotFound(cloud.status())) return NotFound(id);  // deleted meanwhile
    return absl::DataLossError(
        absl::StrCat("stored target '", id, "' cannot be read: ", cloud.status().message()));
  }
  auto built = TimedBuild(std::move(*cloud), should_stop);
  if (absl::IsCancelled(built.status())) return built.status();
  if (!built.ok()) {
    return absl::DataLossError(
        absl::StrCat("stored target '", id, "' cannot be rebuilt: ", built.status().message()));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return NotFound(id);
  Entry& entry = it->second;
  if (!entry.target) {
    const StoredTargetMeta meta = MetaOf(**built, entry.meta.digest);
    if (absl::Status s = MakeRoomLocked(meta.memory_bytes, id); !s.ok()) return s;
    entry.target = *std::move(built);
    entry.meta = meta;
    bytes_ += meta.memory_bytes;
  }
  entry.last_use = ++clock_;
  return entry.target;
}

absl::StatusOr<TargetInfo> TargetCache::Info(std::string_view id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return NotFound(id);
  return InfoLocked(it->first, it->second);
}

std::vector<TargetInfo> TargetCache::List(std::string_view after, std::size_t limit,
                                          bool* more) const {
  std::vector<TargetInfo> page;
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = entries_.upper_bound(after);
  for (; it != entries_.end() && page.size() < limit; ++it) {
    page.push_back(InfoLocked(it->first, it->second));
  }
  *more = it != entries_.end();
  return page;
}

absl::Status TargetCache::Erase(std::string_view id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = entries_.find(id);
  if (it == entries_.end()) return NotFound(id);
  // Files go first, under the lock, so a re-upload of the same id cannot be deleted by mistake.
  if (store_) {
    if (absl::Status s = store_->Remove(it->first); !s.ok()) return s;
  }
  if (const std::shared_ptr<const Target>& target = it->second.target) {
    if (target.use_count() > 1) {  // registrations still hold it: its memory is not free yet
      retired_.emplace_back(target, it->second.meta.memory_bytes);
    } else {
      bytes_ -= it->second.meta.memory_bytes;
    }
  }
  entries_.erase(it);
  return absl::OkStatus();
}

void TargetCache::CountRegistration(std::string_view id) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (const auto it = entries_.find(id); it != entries_.end()) ++it->second.registrations;
}

CacheCounters TargetCache::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  PruneRetiredLocked();
  CacheCounters c;
  c.bytes = bytes_;
  c.budget_bytes = budget_bytes_;
  c.entries = static_cast<int>(entries_.size());
  c.hits = hits_;
  c.misses = misses_;
  c.evictions = evictions_;
  c.builds = builds_;
  c.build_seconds = build_seconds_;
  return c;
}

}  // namespace mlsreg::server
