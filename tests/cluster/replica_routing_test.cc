// Scaling out: three real servers on loopback ports, one client routing by target id.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <set>
#include <thread>

#include "mlsreg/client/client.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "server/server.h"

namespace mlsreg {
namespace {

std::unique_ptr<server::MlsregServer> StartServer() {
  server::ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.workers = 1;
  config.drain_seconds = 0.2;
  auto started = server::MlsregServer::Start(config);
  EXPECT_TRUE(started.ok()) << started.status();
  return started.ok() ? *std::move(started) : nullptr;
}

RegistrationOptions FastOptions() {
  RegistrationOptions o;
  o.num_samples = 300;
  o.max_iterations = 15;
  return o;
}

TEST(ReplicaRoutingTest, SpreadsTargetsAndSurvivesALostReplica) {
  std::vector<std::unique_ptr<server::MlsregServer>> servers;
  std::string addresses;
  for (int i = 0; i < 3; ++i) {
    servers.push_back(StartServer());
    ASSERT_NE(servers.back(), nullptr);
    addresses += (i ? "," : "") + servers.back()->address();
  }
  client::ClientOptions options;
  options.address = addresses;
  options.max_attempts = 6;
  options.initial_backoff_seconds = 0.05;
  auto routed = client::Client::Connect(options);
  ASSERT_TRUE(routed.ok());
  client::Client& client = **routed;
  ASSERT_EQ(client.replicas().size(), 3u);

  // Three scans, six target ids chosen so that every replica owns exactly two of them.
  const std::string dir = std::string(MLSREG_SOURCE_DIR) + "/data/bunny/";
  std::vector<std::shared_ptr<const PointCloud>> clouds;
  for (const char* name : {"bun000.ply", "bun045.ply", "bun315.ply"}) {
    auto cloud = ReadPointCloud(dir + name);
    ASSERT_TRUE(cloud.ok());
    clouds.push_back(std::make_shared<const PointCloud>(*std::move(cloud)));
  }
  std::vector<std::string> ids;
  std::map<std::string, int> per_replica;
  for (int i = 0; ids.size() < 6 && i < 1000; ++i) {
    const std::string id = "target-" + std::to_string(i);
    if (per_replica[client.ReplicaFor(id)] < 2) {
      ++per_replica[client.ReplicaFor(id)];
      ids.push_back(id);
    }
  }
  ASSERT_EQ(ids.size(), 6u);
  auto cloud_of = [&](std::size_t target) { return clouds[target % 3]; };
  for (std::size_t t = 0; t < ids.size(); ++t) {
    ASSERT_TRUE(client.UploadTarget(ids[t], cloud_of(t)).ok());
  }

  // Each target was uploaded to exactly one server: the one its id maps to.
  for (auto& server : servers) {
    client::ClientOptions one;
    one.address = server->address();
    auto direct = client::Client::Connect(one);
    ASSERT_TRUE(direct.ok());
    auto listed = (*direct)->ListTargets();
    ASSERT_TRUE(listed.ok());
    EXPECT_EQ(listed->size(), 2u) << server->address();
    for (const TargetInfo& t : *listed) {
      EXPECT_EQ(client.ReplicaFor(t.id), server->address());
    }
  }

  // The expected answers, in-process (registrations are deterministic).
  std::map<std::pair<int, int>, Matrix4> expected;  // (target cloud, source cloud)
  for (int tc = 0; tc < 3; ++tc) {
    auto target = Target::Build(*clouds[tc]);
    ASSERT_TRUE(target.ok());
    for (int sc = 0; sc < 3; ++sc) {
      auto r = Register(**target, *clouds[sc], Matrix4::Identity(), FastOptions());
      ASSERT_TRUE(r.ok());
      expected[{tc, sc}] = r->transform;
    }
  }

  // 30 jobs from 3 threads; after 8 have finished, the replica owning ids[0] goes away.
  const std::size_t victim = [&] {
    for (std::size_t s = 0; s < servers.size(); ++s) {
      if (servers[s]->address() == client.ReplicaFor(ids[0])) return s;
    }
    return std::size_t{0};
  }();
  constexpr int kJobs = 30;
  std::atomic<int> next{0}, finished{0}, failures{0}, mismatches{0};
  auto worker = [&] {
    for (int job = next++; job < kJobs; job = next++) {
      const int target = job % 6, source = (job / 6) % 3;
      auto r = client.Register(ids[target], *clouds[source], Matrix4::Identity(), FastOptions());
      if (!r.ok()) {
        ++failures;
        ADD_FAILURE() << "job " << job << ": " << r.status();
      } else if (r->result.transform != expected[{target % 3, source}]) {
        ++mismatches;
      }
      ++finished;
    }
  };
  std::vector<std::thread> threads;
  for (int t = 0; t < 3; ++t) threads.emplace_back(worker);
  while (finished < 8) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  servers[victim]->Shutdown();
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(finished, kJobs);
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(mismatches, 0);

  // The victim's targets moved to the survivors (re-uploaded from the client's copy).
  std::set<std::string> surviving;
  for (std::size_t s = 0; s < servers.size(); ++s) {
    if (s == victim) continue;
    client::ClientOptions one;
    one.address = servers[s]->address();
    auto direct = client::Client::Connect(one);
    ASSERT_TRUE(direct.ok());
    auto listed = (*direct)->ListTargets();
    ASSERT_TRUE(listed.ok());
    for (const TargetInfo& t : *listed) surviving.insert(t.id);
  }
  EXPECT_EQ(surviving.size(), 6u);
}

}  // namespace
}  // namespace mlsreg
