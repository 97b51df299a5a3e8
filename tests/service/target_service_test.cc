// TargetService over a real channel: uploads, listing, deletion, validation of every malformed
// upload, the cache budget and eviction, and persistence across evictions and restarts.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "mlsreg/wire/convert.h"
#include "service_test_support.h"

namespace mlsreg::service_test {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("mlsreg_target_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

TEST(TargetServiceTest, UploadGetListDelete) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());

  v1::Target created;
  ASSERT_TRUE(Upload(client, "bun045", Bun045(), &created).ok());  // 1 MiB chunks
  EXPECT_EQ(created.target_id(), "bun045");
  EXPECT_EQ(created.state(), v1::TARGET_STATE_READY);
  EXPECT_EQ(created.point_count(), Bun045().size());
  // The server built the same target as the library does in-process.
  EXPECT_EQ(created.sampling_distance(), Bun045Target()->sampling_distance());
  EXPECT_GT(created.memory_bytes(), Bun045().size() * 24);
  EXPECT_GT(created.build_seconds(), 0.0);

  v1::Target got;
  ASSERT_TRUE(GetTarget(client, "bun045", &got).ok());
  EXPECT_EQ(got.state(), v1::TARGET_STATE_READY);
  EXPECT_EQ(got.point_count(), Bun045().size());
  EXPECT_GT(got.sampling_distance(), 0.0);

  // Small float32 targets for paging; ids come back sorted.
  for (const char* id : {"c-small", "a-small", "b-small"}) {
    ASSERT_TRUE(
        Upload(client, id, Prefix(Bun000(), 300), nullptr, 1024, v1::SCALAR_TYPE_FLOAT32).ok());
  }
  std::vector<std::string> ids;
  std::string token;
  int pages = 0;
  do {
    grpc::ClientContext context;
    client.Prepare(&context);
    v1::ListTargetsRequest request;
    request.set_page_size(3);
    request.set_page_token(token);
    v1::ListTargetsResponse page;
    ASSERT_TRUE(client.targets->ListTargets(&context, request, &page).ok());
    for (const auto& t : page.targets()) ids.push_back(t.target_id());
    token = page.next_page_token();
    ++pages;
  } while (!token.empty() && pages < 10);
  EXPECT_EQ(pages, 2);
  EXPECT_EQ(ids, (std::vector<std::string>{"a-small", "b-small", "bun045", "c-small"}));

  grpc::ClientContext context;
  client.Prepare(&context);
  v1::DeleteTargetRequest del;
  del.set_target_id("bun045");
  v1::DeleteTargetResponse deleted;
  ASSERT_TRUE(client.targets->DeleteTarget(&context, del, &deleted).ok());
  EXPECT_EQ(GetTarget(client, "bun045", &got).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(Stats(client).cache_entries(), 3);
}

TEST(TargetServiceTest, MalformedUploadsNameTheField) {
  ServerConfig config = TestConfig();
  config.max_chunk_bytes = 256 << 10;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  const PointCloud small = Prefix(Bun000(), 20000);  // 480 KB of float64
  v1::Target out;

  EXPECT_STATUS(Upload(client, "../etc/passwd", small), grpc::StatusCode::INVALID_ARGUMENT,
                "header.target_id");
  EXPECT_STATUS(Upload(client, std::string(129, 'a'), small), grpc::StatusCode::INVALID_ARGUMENT,
                "header.target_id");

  auto messages = CreateMessages("t", small, 128 << 10);
  {  // zero points
    auto m = messages;
    m[0].mutable_header()->mutable_cloud()->set_point_count(0);
    m.resize(1);
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT,
                  "header.cloud.point_count");
  }
  {  // no scalar type
    auto m = messages;
    m[0].mutable_header()->mutable_cloud()->set_scalar_type(v1::SCALAR_TYPE_UNSPECIFIED);
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT,
                  "header.cloud.scalar_type");
  }
  {  // NaN coordinate in point 7
    PointCloud bad = small;
    bad.points[7].y() = std::numeric_limits<double>::quiet_NaN();
    EXPECT_STATUS(Upload(client, "t", bad, nullptr, 128 << 10), grpc::StatusCode::INVALID_ARGUMENT,
                  "cloud.points[7]");
  }
  {  // chunks out of order
    auto m = messages;
    std::swap(m[1], m[2]);
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT, "chunk.offset");
  }
  {  // a chunk above max_chunk_bytes
    EXPECT_STATUS(Upload(client, "t", small, nullptr, 300 << 10),
                  grpc::StatusCode::INVALID_ARGUMENT, "chunk.data");
  }
  {  // fewer bytes than declared
    auto m = messages;
    m.pop_back();
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT, "chunk");
  }
  {  // more bytes than declared
    auto m = messages;
    m[0].mutable_header()->mutable_cloud()->set_point_count(small.size() - 1);
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT, "chunk.data");
  }
  {  // the first message is not the header
    auto m = messages;
    m.erase(m.begin());
    EXPECT_STATUS(SendCreate(client, m), grpc::StatusCode::INVALID_ARGUMENT, "header");
  }
  {  // too few points to build a target
    EXPECT_STATUS(Upload(client, "t", Prefix(small, 5)), grpc::StatusCode::INVALID_ARGUMENT,
                  "cloud");
  }
  // None of that left anything behind, and the id is still free.
  EXPECT_EQ(Stats(client).cache_entries(), 0);
  ASSERT_TRUE(SendCreate(client, messages, &out).ok());
  // The same content again is fine (idempotent); other content under the id is refused.
  EXPECT_TRUE(SendCreate(client, messages).ok());
  EXPECT_STATUS(Upload(client, "t", Prefix(small, 50)), grpc::StatusCode::ALREADY_EXISTS,
                "'t' already exists with other content");
}

TEST(TargetServiceTest, TargetLargerThanTheBudgetIsRefusedBeforeItsData) {
  ServerConfig config = TestConfig();
  config.cache_budget_bytes = 1 << 20;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  auto messages = CreateMessages("big", Bun045());
  messages.resize(1);  // the header alone must be enough to refuse it
  EXPECT_STATUS(SendCreate(client, messages), grpc::StatusCode::RESOURCE_EXHAUSTED, "budget");
}

// Budget for exactly one bunny target.
ServerConfig OneTargetConfig() {
  ServerConfig config = TestConfig();
  auto other = Target::Build(Bun000());
  EXPECT_TRUE(other.ok());
  const std::uint64_t largest = std::max(Bun045Target()->MemoryBytes(), (*other)->MemoryBytes());
  config.cache_budget_bytes = largest * 3 / 2;
  return config;
}

TEST(TargetServiceTest, EvictionWithoutDataDirForgetsTheIdleTarget) {
  auto server = StartServer(OneTargetConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "first", Bun045()).ok());
  ASSERT_TRUE(Upload(client, "second", Bun000()).ok());
  v1::Target got;
  EXPECT_EQ(GetTarget(client, "first", &got).error_code(), grpc::StatusCode::NOT_FOUND);
  ASSERT_TRUE(GetTarget(client, "second", &got).ok());
  const v1::GetStatsResponse stats = Stats(client);
  EXPECT_EQ(stats.cache_evictions(), 1u);
  EXPECT_EQ(stats.cache_entries(), 1);
  EXPECT_LE(stats.cache_bytes(), stats.cache_budget_bytes());
}

TEST(TargetServiceTest, EvictedTargetIsReloadedFromTheDataDirOnRegister) {
  const fs::path dir = TempDir("evict");
  ServerConfig config = OneTargetConfig();
  config.data_dir = dir.string();
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bun045", Bun045()).ok());
  ASSERT_TRUE(Upload(client, "other", Bun000()).ok());
  v1::Target got;
  ASSERT_TRUE(GetTarget(client, "bun045", &got).ok());
  EXPECT_EQ(got.state(), v1::TARGET_STATE_STORED);
  EXPECT_EQ(got.point_count(), Bun045().size());
  EXPECT_EQ(got.sampling_distance(), Bun045Target()->sampling_distance());

  const RegisterOutcome outcome = RunRegister(
      client, RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 1)));
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();
  ASSERT_NE(outcome.result(), nullptr);
  EXPECT_EQ(outcome.result()->sampling_distance(), Bun045Target()->sampling_distance());

  ASSERT_TRUE(GetTarget(client, "bun045", &got).ok());
  EXPECT_EQ(got.state(), v1::TARGET_STATE_READY);
  EXPECT_EQ(got.registrations(), 1u);
  ASSERT_TRUE(GetTarget(client, "other", &got).ok());
  EXPECT_EQ(got.state(), v1::TARGET_STATE_STORED);  // made room for the reload
  const v1::GetStatsResponse stats = Stats(client);
  EXPECT_EQ(stats.cache_misses(), 1u);
  EXPECT_EQ(stats.cache_evictions(), 2u);
  server.reset();
  fs::remove_all(dir);
}

TEST(TargetServiceTest, RestartWithTheSameDataDirKeepsTargets) {
  const fs::path dir = TempDir("restart");
  ServerConfig config = TestConfig();
  config.data_dir = dir.string();
  {
    auto server = StartServer(config);
    ASSERT_NE(server, nullptr);
    const Client client = Connect(server->port());
    ASSERT_TRUE(Upload(client, "bun045", Bun045()).ok());
    ASSERT_TRUE(Upload(client, "doomed", Prefix(Bun000(), 500)).ok());
    server->Shutdown();
  }
  {
    auto server = StartServer(config);
    ASSERT_NE(server, nullptr);
    const Client client = Connect(server->port());
    grpc::ClientContext context;
    client.Prepare(&context);
    v1::ListTargetsResponse list;
    ASSERT_TRUE(client.targets->ListTargets(&context, {}, &list).ok());
    ASSERT_EQ(list.targets_size(), 2);
    EXPECT_EQ(list.targets(0).target_id(), "bun045");
    EXPECT_EQ(list.targets(0).state(), v1::TARGET_STATE_STORED);
    EXPECT_EQ(list.targets(0).point_count(), Bun045().size());

    const RegisterOutcome outcome = RunRegister(
        client, RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 2)));
    ASSERT_TRUE(outcome.status.ok()) << outcome.status.error_message();
    ASSERT_NE(outcome.result(), nullptr);

    grpc::ClientContext del_context;
    client.Prepare(&del_context);
    v1::DeleteTargetRequest del;
    del.set_target_id("doomed");
    v1::DeleteTargetResponse deleted;
    ASSERT_TRUE(client.targets->DeleteTarget(&del_context, del, &deleted).ok());
    EXPECT_FALSE(fs::exists(dir / "targets" / "doomed.ply"));
  }
  {
    auto server = StartServer(config);
    ASSERT_NE(server, nullptr);
    const Client client = Connect(server->port());
    v1::Target got;
    EXPECT_TRUE(GetTarget(client, "bun045", &got).ok());
    EXPECT_EQ(GetTarget(client, "doomed", &got).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mlsreg::service_test
