// The server's building blocks on their own: config loading and validation, the job pool's
// admission control, token checks and the target cache's eviction rules.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>

#include "server/auth.h"
#include "server/job_pool.h"
#include "server/registration_job.h"
#include "server/server_config.h"
#include "server/target_cache.h"
#include "support/synthetic.h"

namespace mlsreg::server {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("mlsreg_components_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// ---------------------------------------------------------------------------- config

TEST(ServerConfigTest, LoadsEveryKeyAndRejectsUnknownOrMistypedKeys) {
  const fs::path dir = TempDir("config");
  const fs::path path = dir / "server.json";
  std::ofstream(path) << R"({"listen": "0.0.0.0:6000", "workers": 3, "queue_capacity": 7,
      "cache_budget_bytes": 1048576, "data_dir": "/var/lib/mlsreg", "max_points": 1000,
      "max_message_bytes": 8388608, "max_chunk_bytes": 1048576, "max_concurrent_rpcs": 16,
      "allow_insecure_remote": true, "token": "t", "admin_token": "a", "drain_seconds": 2.5})";
  ServerConfig config;
  ASSERT_TRUE(LoadConfigFile(path.string(), &config).ok());
  EXPECT_EQ(config.listen, "0.0.0.0:6000");
  EXPECT_EQ(config.workers, 3);
  EXPECT_EQ(config.queue_capacity, 7);
  EXPECT_EQ(config.cache_budget_bytes, 1048576u);
  EXPECT_EQ(config.data_dir, "/var/lib/mlsreg");
  EXPECT_EQ(config.max_points, 1000u);
  EXPECT_EQ(config.max_chunk_bytes, 1048576);
  EXPECT_TRUE(config.allow_insecure_remote);
  EXPECT_EQ(config.admin_token, "a");
  EXPECT_DOUBLE_EQ(config.drain_seconds, 2.5);
  EXPECT_TRUE(Validate(config).ok()) << Validate(config);

  std::ofstream(path) << R"({"wokers": 3})";
  absl::Status s = LoadConfigFile(path.string(), &config);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("wokers"), absl::string_view::npos) << s;

  std::ofstream(path) << R"({"workers": "three"})";
  s = LoadConfigFile(path.string(), &config);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("workers"), absl::string_view::npos) << s;
  fs::remove_all(dir);
}

TEST(ServerConfigTest, RefusesPlaintextOnRemoteAddressesAndUnreadableCertificates) {
  ServerConfig config;
  config.listen = "0.0.0.0:50051";
  absl::Status s = Validate(config);
  EXPECT_EQ(s.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(s.message().find("plaintext"), absl::string_view::npos) << s;
  config.allow_insecure_remote = true;
  EXPECT_TRUE(Validate(config).ok());

  for (const char* loopback : {"127.0.0.1:1", "localhost:1", "[::1]:1", "unix:/tmp/x.sock"}) {
    EXPECT_TRUE(IsLoopbackAddress(loopback)) << loopback;
  }
  for (const char* remote : {"0.0.0.0:1", "[::]:1", "10.0.0.1:1", "example.com:1"}) {
    EXPECT_FALSE(IsLoopbackAddress(remote)) << remote;
  }

  config = ServerConfig();
  config.tls_cert = "/nonexistent/server.pem";
  config.tls_key = "/nonexistent/server.key";
  s = Validate(config);
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("/nonexistent/server.pem"), absl::string_view::npos) << s;

  config = ServerConfig();
  config.tls_cert = "/etc/hostname";  // readable, but no key
  EXPECT_EQ(Validate(config).code(), absl::StatusCode::kInvalidArgument);
  config = ServerConfig();
  config.max_chunk_bytes = 64 << 20;  // a chunk must fit in a message
  EXPECT_EQ(Validate(config).code(), absl::StatusCode::kInvalidArgument);
}

// ---------------------------------------------------------------------------- job pool

TEST(JobPoolTest, AdmitsOneRunningAndCapacityQueuedJobsThenRefuses) {
  std::atomic<bool> released{false};
  std::atomic<int> started{0};
  auto blocker = [&] {
    started.fetch_add(1);
    while (!released.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  JobPool pool(/*workers=*/1, /*queue_capacity=*/1);
  // Declared after the pool: releases the jobs before the pool joins, even when a check fails.
  const std::shared_ptr<void> release(nullptr, [&](void*) { released.store(true); });
  auto first = pool.TrySubmit(blocker);
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(*first, 0);
  // The worker may not have picked the first job yet; the second is admitted either way.
  auto second = pool.TrySubmit(blocker);
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ(*second, 0);  // next in line
  ASSERT_TRUE([&] {
    for (int i = 0; i < 500 && pool.active() != 1; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return pool.active() == 1;
  }());
  EXPECT_EQ(pool.queued(), 1);
  auto third = pool.TrySubmit(blocker);
  EXPECT_EQ(third.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(third.status().message(), "job queue full (capacity 1)");
  released.store(true);
  pool.Shutdown();  // drains: the queued job runs too
  EXPECT_EQ(started.load(), 2);
  EXPECT_EQ(pool.TrySubmit([] {}).status().code(), absl::StatusCode::kUnavailable);
}

// ---------------------------------------------------------------------------- registration job

// A job still queued when the drain time runs out never starts, and says why in a way the client
// can act on: a shutdown is UNAVAILABLE (retry on another replica), not CANCELLED.
TEST(RegistrationJobTest, JobStoppedBeforeItStartsReportsItsCause) {
  auto target = Target::Build(testing::SamplePlaneGrid(1.0, 0.05, 0.01, 1));
  ASSERT_TRUE(target.ok()) << target.status();
  auto make_input = [&] {
    RegistrationInput input;
    input.target_id = "plane";
    input.target = *target;
    input.source = testing::SamplePlaneGrid(1.0, 0.05, 0.01, 2);
    return input;
  };
  std::atomic<bool> stop{true};
  RegistrationJob shut_down(make_input(), /*cache=*/nullptr, &stop);
  shut_down.Run();
  EXPECT_EQ(shut_down.stop_cause(), StopCause::kShutdown);
  EXPECT_EQ(shut_down.outcome().status().code(), absl::StatusCode::kUnavailable);
  EXPECT_EQ(shut_down.outcome().status().message(),
            "server shutting down: registration stopped before its first iteration; retry on "
            "another server");

  stop.store(false);
  RegistrationJob cancelled(make_input(), nullptr, &stop);
  cancelled.Cancel();
  cancelled.Run();
  EXPECT_EQ(cancelled.outcome().status().code(), absl::StatusCode::kCancelled);

  RegistrationInput late = make_input();
  late.deadline = std::chrono::system_clock::now() - std::chrono::seconds(1);
  RegistrationJob expired(std::move(late), nullptr, &stop);
  expired.Run();
  EXPECT_EQ(expired.outcome().status().code(), absl::StatusCode::kDeadlineExceeded);
}

// ---------------------------------------------------------------------------- auth

TEST(TokenAuthenticatorTest, UserAndAdminTokens) {
  const TokenAuthenticator auth("user-secret", "admin-secret");
  EXPECT_EQ(auth.Check(std::nullopt, Access::kUser).code(), absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(auth.Check("Bearer wrong", Access::kUser).code(), absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(auth.Check("Basic user-secret", Access::kUser).code(),
            absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(auth.Check("Bearer user-secre", Access::kUser).code(),
            absl::StatusCode::kUnauthenticated);
  EXPECT_TRUE(auth.Check("Bearer user-secret", Access::kUser).ok());
  EXPECT_TRUE(auth.Check("bearer user-secret", Access::kUser).ok());
  EXPECT_TRUE(auth.Check("Bearer admin-secret", Access::kUser).ok());
  EXPECT_EQ(auth.Check("Bearer user-secret", Access::kAdmin).code(),
            absl::StatusCode::kPermissionDenied);
  EXPECT_TRUE(auth.Check("Bearer admin-secret", Access::kAdmin).ok());

  const TokenAuthenticator open("", "");
  EXPECT_TRUE(open.Check(std::nullopt, Access::kAdmin).ok());
  const TokenAuthenticator admin_only("", "admin-secret");
  EXPECT_TRUE(admin_only.Check(std::nullopt, Access::kUser).ok());
  EXPECT_EQ(admin_only.Check(std::nullopt, Access::kAdmin).code(),
            absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(admin_only.Check("Bearer nope", Access::kAdmin).code(),
            absl::StatusCode::kUnauthenticated);

  EXPECT_TRUE(ConstantTimeEquals("abc", "abc"));
  EXPECT_FALSE(ConstantTimeEquals("abcd", "abc"));
  EXPECT_FALSE(ConstantTimeEquals("ab", "abc"));
  EXPECT_FALSE(ConstantTimeEquals("", "abc"));
}

// ---------------------------------------------------------------------------- target cache

std::shared_ptr<const Target> SmallTarget(std::uint64_t seed) {
  auto built = Target::Build(testing::SampleBumpySurface(2000, -1, 1, seed));
  EXPECT_TRUE(built.ok()) << built.status();
  return *built;
}

TEST(TargetCacheTest, EvictsTheLeastRecentlyUsedIdleTargetNeverOneInUse) {
  auto a = SmallTarget(1), b = SmallTarget(2), c = SmallTarget(3);
  const std::uint64_t size = std::max({a->MemoryBytes(), b->MemoryBytes(), c->MemoryBytes()});
  auto cache = TargetCache::Open(2 * size + size / 2, nullptr);  // room for two
  ASSERT_TRUE(cache.ok());
  TargetCache& targets = **cache;
  // Handed over: a reference kept here would count as a registration using the target.
  ASSERT_TRUE(targets.Insert("a", std::move(a)).ok());
  ASSERT_TRUE(targets.Insert("b", std::move(b)).ok());
  EXPECT_EQ(targets.Insert("a", SmallTarget(5)).status().code(), absl::StatusCode::kAlreadyExists);

  // "a" is older, but a registration holds it: "b" is the one to go.
  auto held = targets.Peek("a");
  ASSERT_TRUE(held.ok() && *held);
  ASSERT_TRUE(targets.Insert("c", std::move(c)).ok());
  EXPECT_TRUE(targets.Info("a").ok());
  EXPECT_EQ(targets.Info("b").status().code(), absl::StatusCode::kNotFound);  // no store: gone
  EXPECT_EQ(targets.counters().evictions, 1u);

  // Everything resident in use: a new target cannot fit, and nothing is evicted trying.
  auto held_c = targets.Peek("c");
  auto refused = targets.Insert("d", SmallTarget(4));
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kResourceExhausted) << refused.status();
  EXPECT_EQ(targets.counters().entries, 2);
  EXPECT_EQ(targets.counters().evictions, 1u);
  EXPECT_EQ(targets.CheckCanCreate("e", 3 * size).code(), absl::StatusCode::kResourceExhausted);
}

TEST(TargetCacheTest, StoreKeepsEvictedTargetsAndReloadsThem) {
  const fs::path dir = TempDir("store");
  auto a = SmallTarget(1), b = SmallTarget(2);
  const std::uint64_t budget = std::max(a->MemoryBytes(), b->MemoryBytes()) * 3 / 2;  // one fits
  const std::vector<Vec3> a_points = a->points();
  const double a_d = a->sampling_distance();
  {
    auto store = TargetStore::Open(dir.string());
    ASSERT_TRUE(store.ok());
    auto cache = TargetCache::Open(budget, *std::move(store));
    ASSERT_TRUE(cache.ok());
    ASSERT_TRUE((*cache)->Insert("a", std::move(a)).ok());
    ASSERT_TRUE((*cache)->Insert("b", std::move(b)).ok());
    auto info = (*cache)->Info("a");
    ASSERT_TRUE(info.ok());
    EXPECT_EQ(info->state, TargetState::kStored);
    EXPECT_EQ(info->point_count, 2000u);
    auto reloaded = (*cache)->Acquire("a");
    ASSERT_TRUE(reloaded.ok()) << reloaded.status();
    EXPECT_EQ((*reloaded)->points(), a_points);  // bit-exact round trip through the PLY
    EXPECT_EQ((*reloaded)->sampling_distance(), a_d);
    EXPECT_EQ((*cache)->counters().misses, 1u);
    ASSERT_TRUE((*cache)->Erase("b").ok());
    EXPECT_FALSE(fs::exists(dir / "targets" / "b.ply"));
  }
  auto store = TargetStore::Open(dir.string());
  ASSERT_TRUE(store.ok());
  auto cache = TargetCache::Open(budget, *std::move(store));
  ASSERT_TRUE(cache.ok());
  bool more = true;
  const std::vector<TargetInfo> listed = (*cache)->List("", 10, &more);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed[0].id, "a");
  EXPECT_EQ(listed[0].state, TargetState::kStored);
  EXPECT_FALSE(more);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mlsreg::server
