// The server's building blocks on their own: config loading and validation, the job pool's
// admission control, token checks and the target cache's eviction rules.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>

#include "mlsreg/core/cloud_digest.h"
#include "server/auth.h"
#include "server/inflight_budget.h"
#include "server/job_pool.h"
#include "server/registration_job.h"
#include "server/retry_hint.h"
#include "server/server_config.h"
#include "server/stream_guard.h"
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

  for (const char* loopback : {"127.0.0.1:1", "127.1.2.3:1", "localhost:1", "[::1]:1",
                               "[::ffff:127.0.0.1]:1", "unix:/tmp/x.sock"}) {
    EXPECT_TRUE(IsLoopbackAddress(loopback)) << loopback;
  }
  // Host names resolve to anything, whatever they start with.
  for (const char* remote : {"0.0.0.0:1", "[::]:1", "10.0.0.1:1", "example.com:1",
                             "127.example.com:1", "127.0.0.1.nip.io:1", "1270.0.0.1:1"}) {
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
  for (int threads : {0, 257}) {  // threads inside one job
    config = ServerConfig();
    config.job_threads = threads;
    s = Validate(config);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(s.message().find("job_threads"), absl::string_view::npos) << s;
  }
}

TEST(ServerConfigTest, ListenAddressesNeedAPortInRangeAndMessagesNameTheFlag) {
  // gRPC takes 99999 modulo 65536 (it would listen on 34463): refused before anything listens.
  for (const char* bad : {"127.0.0.1:99999", "127.0.0.1:65536", "127.0.0.1",
                          "127.0.0.1:", "127.0.0.1:50x", "[::1]", ":50051"}) {
    ServerConfig config;
    config.listen = bad;
    absl::Status s = Validate(config);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("listen (--listen): "), absl::string_view::npos) << s;
    config = ServerConfig();
    config.metrics_listen = bad;
    s = Validate(config);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("metrics_listen (--metrics-listen): "), absl::string_view::npos)
        << s;
  }
  ServerConfig config;
  config.listen = "127.0.0.1:99999";
  EXPECT_NE(Validate(config).message().find("port 99999"), absl::string_view::npos);
  for (const char* good :
       {"127.0.0.1:0", "127.0.0.1:65535", "localhost:50051", "[::1]:50051", "unix:/tmp/m.sock"}) {
    config.listen = good;
    EXPECT_TRUE(Validate(config).ok()) << good << ": " << Validate(config);
  }
  config = ServerConfig();
  config.workers = -1;
  EXPECT_NE(Validate(config).message().find("workers (--workers): "), absl::string_view::npos);
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

// A job that throws (std::bad_alloc from a huge allocation, say) fails alone: its caller hears
// INTERNAL naming the exception and the worker takes the next job.
TEST(JobPoolTest, AJobThatThrowsFailsWithInternalAndTheWorkerGoesOn) {
  JobPool pool(/*workers=*/1, /*queue_capacity=*/4);
  std::atomic<int> failures{0};
  std::string message;
  std::mutex mutex;
  ASSERT_TRUE(pool.TrySubmit([] { throw std::bad_alloc(); },
                             [&](absl::Status s) {
                               std::lock_guard<std::mutex> lock(mutex);
                               EXPECT_EQ(s.code(), absl::StatusCode::kInternal);
                               message = std::string(s.message());
                               failures.fetch_add(1);
                             })
                  .ok());
  std::atomic<bool> ran{false};
  ASSERT_TRUE(pool.TrySubmit([&] { ran.store(true); }).ok());
  pool.Shutdown();
  EXPECT_EQ(failures.load(), 1);
  EXPECT_TRUE(ran.load());
  EXPECT_NE(message.find("bad_alloc"), std::string::npos) << message;
}

// Admission before transfer: CheckRoom answers what TrySubmit would, and holds nothing.
TEST(JobPoolTest, CheckRoomAnswersLikeTrySubmitAndHoldsNothing) {
  std::atomic<bool> released{false};
  JobPool pool(/*workers=*/1, /*queue_capacity=*/1);
  const std::shared_ptr<void> release(nullptr, [&](void*) { released.store(true); });
  auto blocker = [&] {
    while (!released.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  };
  ASSERT_TRUE(pool.TrySubmit(blocker).ok());
  for (int i = 0; i < 500 && pool.active() != 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_EQ(pool.active(), 1);
  EXPECT_TRUE(pool.CheckRoom().ok());
  EXPECT_TRUE(pool.CheckRoom().ok());  // asking twice took nothing
  ASSERT_TRUE(pool.TrySubmit(blocker).ok());
  EXPECT_EQ(pool.CheckRoom().code(), absl::StatusCode::kResourceExhausted);
  released.store(true);
}

// ---------------------------------------------------------------------------- budgets, streams

TEST(InFlightBudgetTest, LeasesGrowWithTheDataAndRefusalsSayWhetherToRetry) {
  InFlightBudget budget(1000);
  EXPECT_TRUE(budget.Check(1000, "header.source").ok());  // checks hold nothing
  EXPECT_EQ(budget.used(), 0u);
  auto never = budget.Check(1001, "header.cloud");
  EXPECT_EQ(never.code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(RetryAfterValue(never), "-1");
  {
    InFlightBudget::Lease a(&budget);
    ASSERT_TRUE(a.Grow(400, "chunk").ok());
    ASSERT_TRUE(a.Grow(200, "chunk").ok());
    EXPECT_EQ(budget.used(), 600u);
    const absl::Status later = budget.Check(600, "header.source");
    EXPECT_EQ(later.code(), absl::StatusCode::kResourceExhausted);
    EXPECT_NE(later.message().find("header.source"), std::string::npos);
    EXPECT_EQ(RetryAfterValue(later), "200");
    InFlightBudget::Lease b(&budget);
    EXPECT_EQ(b.Grow(401, "source_chunk").code(), absl::StatusCode::kResourceExhausted);
    a.Shrink(100);
    EXPECT_TRUE(b.Grow(401, "source_chunk").ok());
    EXPECT_EQ(budget.used(), 901u);
  }
  EXPECT_EQ(budget.used(), 0u);  // given back with the leases
}

TEST(StreamLimiterTest, LimitsEachClientThenEachHost) {
  EXPECT_EQ(PeerHost("ipv4:127.0.0.1:40000"), "ipv4:127.0.0.1");
  EXPECT_EQ(PeerHost("ipv6:[::1]:40000"), "ipv6:[::1]");
  StreamLimiter limiter(/*max_per_client=*/2, /*max_per_host=*/3);
  // Without tokens, the host's ceiling is the limit.
  auto a = limiter.Open("ipv4:10.0.0.1:1000", "");
  auto b = limiter.Open("ipv4:10.0.0.1:1001", "");
  auto c = limiter.Open("ipv4:10.0.0.1:1002", "");
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  auto d = limiter.Open("ipv4:10.0.0.1:1003", "");
  EXPECT_EQ(d.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(d.status().message().find("per host, max_streams_per_peer"), absl::string_view::npos);
  EXPECT_TRUE(limiter.Open("ipv4:10.0.0.2:1000", "").ok());  // another host is not affected
  { StreamLimiter::Ticket gone = *std::move(a); }
  EXPECT_TRUE(limiter.Open("ipv4:10.0.0.1:1003", "").ok());
  // A client (token) reaches its own limit first, wherever it connects from; another client on
  // the same host is not affected until the host's ceiling.
  StreamLimiter fair(/*max_per_client=*/2, /*max_per_host=*/5);
  auto x1 = fair.Open("ipv4:10.0.0.1:1", "token 1");
  auto x2 = fair.Open("ipv4:10.0.0.9:1", "token 1");
  ASSERT_TRUE(x1.ok() && x2.ok());
  auto x3 = fair.Open("ipv4:10.0.0.1:2", "token 1");
  EXPECT_EQ(x3.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_NE(x3.status().message().find("token 1; limit 2 per client, max_streams_per_client"),
            absl::string_view::npos)
      << x3.status();
  EXPECT_EQ(RetryAfterValue(x3.status()), "1000");
  auto y1 = fair.Open("ipv4:10.0.0.1:3", "token 2");
  auto y2 = fair.Open("ipv4:10.0.0.1:4", "token 2");
  EXPECT_TRUE(y1.ok() && y2.ok());
  EXPECT_EQ(fair.open_streams(), 4);
}

TEST(TokenAuthenticatorTest, EachTokenOfAFileIsAClientOfItsOwn) {
  const TokenAuthenticator auth("first\n\n  second  \nthird\n", "admin-secret");
  EXPECT_EQ(*auth.Authenticate("Bearer first", Access::kUser), "token 1");
  EXPECT_EQ(*auth.Authenticate("Bearer second", Access::kUser), "token 2");
  EXPECT_EQ(*auth.Authenticate("Bearer third", Access::kUser), "token 3");
  EXPECT_EQ(*auth.Authenticate("Bearer admin-secret", Access::kUser), "admin");
  EXPECT_EQ(auth.Authenticate("Bearer first\nsecond", Access::kUser).status().code(),
            absl::StatusCode::kUnauthenticated);
  EXPECT_EQ(*TokenAuthenticator("", "").Authenticate(std::nullopt, Access::kUser), "");
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

// Inserts with the target's true content digest, as the upload path does.
absl::StatusOr<TargetInfo> Insert(TargetCache& cache, const std::string& id,
                                  std::shared_ptr<const Target> target) {
  const std::string digest = CloudDigest(target->cloud());
  return cache.Insert(id, std::move(target), digest);
}

TEST(TargetCacheTest, EvictsTheLeastRecentlyUsedIdleTargetNeverOneInUse) {
  auto a = SmallTarget(1), b = SmallTarget(2), c = SmallTarget(3);
  const std::uint64_t size = std::max({a->MemoryBytes(), b->MemoryBytes(), c->MemoryBytes()});
  auto cache = TargetCache::Open(2 * size + size / 2, nullptr);  // room for two
  ASSERT_TRUE(cache.ok());
  TargetCache& targets = **cache;
  // Handed over: a reference kept here would count as a registration using the target.
  ASSERT_TRUE(Insert(targets, "a", std::move(a)).ok());
  ASSERT_TRUE(Insert(targets, "b", std::move(b)).ok());
  EXPECT_EQ(Insert(targets, "a", SmallTarget(5)).status().code(), absl::StatusCode::kAlreadyExists);

  // "a" is older, but a registration holds it: "b" is the one to go.
  auto held = targets.Peek("a");
  ASSERT_TRUE(held.ok() && *held);
  ASSERT_TRUE(Insert(targets, "c", std::move(c)).ok());
  EXPECT_TRUE(targets.Info("a").ok());
  EXPECT_EQ(targets.Info("b").status().code(), absl::StatusCode::kNotFound);  // no store: gone
  EXPECT_EQ(targets.counters().evictions, 1u);

  // Everything resident in use: a new target cannot fit, and nothing is evicted trying.
  auto held_c = targets.Peek("c");
  auto refused = Insert(targets, "d", SmallTarget(4));
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kResourceExhausted) << refused.status();
  EXPECT_EQ(targets.counters().entries, 2);
  EXPECT_EQ(targets.counters().evictions, 1u);
  EXPECT_EQ(RetryAfterValue(refused.status()), "1000");  // in use now: worth a retry later
  auto never = targets.CheckCanCreate("e", 3 * size, "");
  EXPECT_EQ(never.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ(RetryAfterValue(never.status()), "-1");  // larger than the budget: never
}

TEST(TargetCacheTest, TheSameIdWithTheSameContentIsIdempotentAndOtherContentIsRefused) {
  auto cache = TargetCache::Open(std::uint64_t{1} << 30, nullptr);
  ASSERT_TRUE(cache.ok());
  TargetCache& targets = **cache;
  auto a = SmallTarget(1);
  const std::string digest = CloudDigest(a->cloud());
  ASSERT_TRUE(targets.Insert("a", a, digest).ok());
  // Declared before any data: the same digest is the stored target, another one is refused.
  auto same = targets.CheckCanCreate("a", 1, digest);
  ASSERT_TRUE(same.ok()) << same.status();
  ASSERT_TRUE(same->has_value());
  EXPECT_EQ((*same)->digest, digest);
  const std::string other = CloudDigest(SmallTarget(2)->cloud());
  ASSERT_NE(other, digest);
  auto different = targets.CheckCanCreate("a", 1, other);
  EXPECT_EQ(different.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_NE(different.status().message().find(other), std::string::npos);
  // Not declared: the data decides, so the check lets the upload through.
  auto undeclared = targets.CheckCanCreate("a", 1, "");
  ASSERT_TRUE(undeclared.ok());
  EXPECT_FALSE(undeclared->has_value());
  // Inserting the same content again succeeds and keeps the first target.
  auto again = targets.Insert("a", SmallTarget(1), digest);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(targets.counters().entries, 1);
  EXPECT_EQ(targets.Insert("a", SmallTarget(2), other).status().code(),
            absl::StatusCode::kAlreadyExists);
}

TEST(TargetCacheTest, ADeletedTargetInUseStaysCountedUntilReleased) {
  auto cache = TargetCache::Open(std::uint64_t{1} << 30, nullptr);
  ASSERT_TRUE(cache.ok());
  TargetCache& targets = **cache;
  ASSERT_TRUE(Insert(targets, "a", SmallTarget(1)).ok());
  const std::uint64_t bytes = targets.counters().bytes;
  ASSERT_GT(bytes, 0u);
  {
    auto held = targets.Peek("a");  // a running registration
    ASSERT_TRUE(held.ok() && *held);
    ASSERT_TRUE(targets.Erase("a").ok());
    EXPECT_EQ(targets.counters().bytes, bytes);  // still in memory
    EXPECT_EQ(targets.counters().entries, 0);
  }
  EXPECT_EQ(targets.counters().bytes, 0u);  // released with the last reference
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
    ASSERT_TRUE(Insert(**cache, "a", std::move(a)).ok());
    ASSERT_TRUE(Insert(**cache, "b", std::move(b)).ok());
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
// The one loader: concurrent requests for a stored target, and concurrent uploads of one id,
// wait for a single build instead of each building.
TEST(TargetCacheTest, ConcurrentReloadsAndUploadsOfOneTargetBuildItOnce) {
  const fs::path dir = TempDir("loader");
  {
    auto store = TargetStore::Open(dir.string());
    ASSERT_TRUE(store.ok());
    auto cache = TargetCache::Open(1u << 30, *std::move(store));
    ASSERT_TRUE(cache.ok());
    ASSERT_TRUE(Insert(**cache, "a", SmallTarget(1)).ok());
  }
  auto store = TargetStore::Open(dir.string());
  ASSERT_TRUE(store.ok());
  auto cache = TargetCache::Open(1u << 30, *std::move(store));  // "a" is STORED now
  ASSERT_TRUE(cache.ok());
  TargetCache& targets = **cache;
  const PointCloud b = testing::SampleBumpySurface(20000, -1, 1, 7);
  const std::string b_digest = CloudDigest(b);
  constexpr int kThreads = 6;
  std::vector<std::shared_ptr<const Target>> acquired(kThreads);
  std::vector<absl::Status> uploads(kThreads);
  {
    std::vector<std::thread> threads;
    for (int i = 0; i < kThreads; ++i) {
      threads.emplace_back([&, i] {
        auto t = targets.Acquire("a");
        if (t.ok()) acquired[i] = *t;
        uploads[i] = targets.Create("b", b, b_digest).status();
      });
    }
    for (std::thread& t : threads) t.join();
  }
  for (int i = 0; i < kThreads; ++i) {
    ASSERT_NE(acquired[i], nullptr);
    EXPECT_EQ(acquired[i], acquired[0]);
    EXPECT_TRUE(uploads[i].ok()) << uploads[i];  // idempotent: the same content succeeds
  }
  EXPECT_EQ(targets.counters().builds, 2u);  // "a" rebuilt once, "b" built once
  EXPECT_EQ(targets.Info("b")->point_count, 20000u);
  fs::remove_all(dir);
}

// The estimate is checked before the build: a cloud that can never fit is refused without one.
TEST(TargetCacheTest, AnUploadThatCannotFitIsRefusedBeforeItsBuild) {
  auto cache = TargetCache::Open(100'000, nullptr);
  ASSERT_TRUE(cache.ok());
  const PointCloud big = testing::SampleBumpySurface(20000, -1, 1, 3);  // > 1 MB estimated
  auto created = (*cache)->Create("big", big, CloudDigest(big));
  EXPECT_EQ(created.status().code(), absl::StatusCode::kResourceExhausted);
  EXPECT_EQ((*cache)->counters().builds, 0u);
}

}  // namespace mlsreg::server
