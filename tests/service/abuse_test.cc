// The abuse suite: what a hostile or careless client can do to the real server on 127.0.0.1,
// one test per defect found by probing it (docs/service.md, "Limits"). Each test is bounded in
// count and time, asserts the status and message the abuser gets, and then that the server
// still serves everybody else and that stored targets are intact.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "mlsreg/client/client.h"
#include "mlsreg/wire/convert.h"
#include "service_test_support.h"
#include "support/synthetic.h"

namespace mlsreg::service_test {
namespace {

namespace fs = std::filesystem;

using RegisterStream = grpc::ClientReaderWriter<v1::RegisterRequest, v1::RegisterResponse>;

// Everything still works for a well-behaved client: health, a lookup, an upload and a quick
// registration against the bunny target `target_id` (uploaded by the test).
void ExpectServesOthers(const Client& client, const std::string& target_id) {
  grpc::ClientContext health_context;
  client.Prepare(&health_context, std::chrono::seconds(10));
  grpc::health::v1::HealthCheckResponse health;
  auto health_stub = grpc::health::v1::Health::NewStub(client.channel);
  ASSERT_TRUE(health_stub->Check(&health_context, {}, &health).ok());
  EXPECT_EQ(health.status(), grpc::health::v1::HealthCheckResponse::SERVING);
  v1::Target target;
  ASSERT_TRUE(GetTarget(client, target_id, &target).ok());
  EXPECT_EQ(target.point_count(), Bun045().size());  // intact
  const RegisterOutcome outcome = RunRegister(
      client, RegisterMessages(target_id, Bun000(), QuickOptions(), PerturbedStart(5, 5, 1)),
      std::chrono::seconds(60));
  EXPECT_TRUE(outcome.status.ok()) << outcome.status.error_message();
  EXPECT_NE(outcome.result(), nullptr);
}

std::string RetryAfter(const grpc::ClientContext& context) {
  const auto& trailers = context.GetServerTrailingMetadata();
  const auto it = trailers.find("mlsreg-retry-after-ms");
  return it == trailers.end() ? "" : std::string(it->second.data(), it->second.size());
}

// CreateTarget with only a header (for refusals that must come before any data).
grpc::Status CreateHeaderOnly(const Client& client, const v1::CreateTargetHeader& header,
                              std::string* retry_after = nullptr) {
  grpc::ClientContext context;
  client.Prepare(&context, std::chrono::seconds(20));
  v1::Target out;
  auto writer = client.targets->CreateTarget(&context, &out);
  v1::CreateTargetRequest request;
  *request.mutable_header() = header;
  writer->Write(request);
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  if (retry_after) *retry_after = RetryAfter(context);
  return status;
}

v1::CreateTargetHeader CloudHeaderOf(const std::string& id, std::uint64_t points) {
  v1::CreateTargetHeader header;
  header.set_target_id(id);
  header.mutable_cloud()->set_scalar_type(v1::SCALAR_TYPE_FLOAT64);
  header.mutable_cloud()->set_point_count(points);
  return header;
}

std::uint64_t ResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  }
  return 0;
}

// A stream that sent `messages` and then nothing: the client is alive but silent.
struct SilentStream {
  grpc::ClientContext context;
  std::unique_ptr<RegisterStream> stream;
};

std::unique_ptr<SilentStream> OpenSilentRegister(const Client& client,
                                                 const std::vector<v1::RegisterRequest>& messages,
                                                 std::chrono::seconds timeout) {
  auto s = std::make_unique<SilentStream>();
  client.Prepare(&s->context, timeout);
  s->stream = client.registration->Register(&s->context);
  for (const auto& m : messages) s->stream->Write(m);
  return s;
}

// A Register header that announces a chunked source of the bunny scan, and no chunk.
std::vector<v1::RegisterRequest> HeaderOnlyRegister(const std::string& target_id) {
  auto messages =
      RegisterMessages(target_id, Bun000(), QuickOptions(), PerturbedStart(5, 5, 1), {}, kMiB / 4);
  messages.resize(1);
  return messages;
}

// ---- 1. remote crash: a request of a few hundred bytes asking for a depth image of 1e10 pixels

TEST(AbuseTest, AHugeDepthImageIsRefusedBeforeAnythingIsAllocated) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  const std::uint64_t rss_before = ResidentBytes();
  for (int side : {100000, 20000}) {
    v1::CreateTargetHeader header = CloudHeaderOf("tiny", 16);
    v1::PinholeIntrinsics* k = header.mutable_cloud()->mutable_intrinsics();
    k->set_width(side);
    k->set_height(side);
    k->set_fx(500);
    k->set_fy(500);
    k->set_cx(side / 2.0);
    k->set_cy(side / 2.0);
    EXPECT_STATUS(CreateHeaderOnly(client, header), grpc::StatusCode::INVALID_ARGUMENT,
                  "header.cloud.intrinsics: a " + std::to_string(side) + " x ");
  }
  EXPECT_LT(ResidentBytes(), rss_before + (64u << 20));  // nothing near 1.6 GB was touched
  // A depth image a 16-point scan can plausibly have is fine.
  PointCloud small;
  for (int i = 0; i < 16; ++i) small.points.push_back(Vec3(0.001 * (i % 4), 0.001 * (i / 4), 1.0));
  small.intrinsics = PinholeIntrinsics{64, 48, 500, 500, 32, 24};
  EXPECT_TRUE(Upload(client, "small-organised", small).ok());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  ExpectServesOthers(client, "bunny");
}

// ---- 2. FGR's memory: parameters beyond the bounds are refused, naming them

TEST(AbuseTest, ParametersThatWouldUnboundMemoryAreRefusedNamingTheField) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  struct Case {
    std::function<void(RegistrationOptions&)> set;
    const char* field;
  };
  for (const Case& c : std::vector<Case>{
           {[](RegistrationOptions& o) { o.fgr.samples = 20000; }, "parameters.fgr_samples"},
           {[](RegistrationOptions& o) { o.fgr.feature_radius_d = 1000; },
            "parameters.fgr_feature_radius_d"},
           {[](RegistrationOptions& o) { o.num_samples = 10'000'000; }, "parameters.num_samples"},
       }) {
    RegistrationOptions options = QuickOptions();
    options.method = Method::kFgr;
    c.set(options);
    const RegisterOutcome outcome =
        RunRegister(client, RegisterMessages("bunny", Bun000(), options, Matrix4::Identity()));
    EXPECT_STATUS(outcome.status, grpc::StatusCode::INVALID_ARGUMENT, c.field);
    EXPECT_EQ(outcome.accepted(), nullptr);  // refused before it took a worker
  }
  ExpectServesOthers(client, "bunny");
}

// ---- 3. stalled streams: no thread is held, and the queue is not theirs to fill

TEST(AbuseTest, TwoHundredSixtySilentStreamsHoldNoThreadAndOthersAreServed) {
  ServerConfig config = TestConfig();
  config.max_streams_per_peer = 1000;  // every attacker stream is admitted: the worst case
  config.max_streams_per_connection = 1000;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  std::vector<std::unique_ptr<SilentStream>> silent;
  for (int i = 0; i < 260; ++i) {
    silent.push_back(
        OpenSilentRegister(client, HeaderOnlyRegister("bunny"), std::chrono::seconds(60)));
  }
  // Their headers were checked (queue room, bytes), but a silent call holds neither.
  ASSERT_TRUE(Eventually([&] { return server->open_streams() == 260; }, std::chrono::seconds(20)));
  EXPECT_EQ(Stats(client).queue_depth(), 0);
  ExpectServesOthers(client, "bunny");  // unary RPCs, health, and a registration
  // They end their streams without the data they announced.
  for (auto& s : silent) {
    s->stream->WritesDone();
    EXPECT_STATUS(s->stream->Finish(), grpc::StatusCode::INVALID_ARGUMENT,
                  "the stream ended after 0 of");
  }
  EXPECT_TRUE(Eventually([&] { return server->open_streams() == 0; }, std::chrono::seconds(10)));
}

TEST(AbuseTest, OnePeerCannotOpenMoreThanItsStreams) {
  ServerConfig config = TestConfig();
  config.max_streams_per_peer = 3;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  std::vector<std::unique_ptr<SilentStream>> silent;
  for (int i = 0; i < 3; ++i) {
    silent.push_back(
        OpenSilentRegister(client, HeaderOnlyRegister("bunny"), std::chrono::seconds(60)));
  }
  ASSERT_TRUE(Eventually([&] { return server->open_streams() == 3; }, std::chrono::seconds(20)));
  auto fourth = OpenSilentRegister(client, HeaderOnlyRegister("bunny"), std::chrono::seconds(20));
  fourth->stream->WritesDone();
  const grpc::Status status = fourth->stream->Finish();
  EXPECT_STATUS(status, grpc::StatusCode::RESOURCE_EXHAUSTED,
                "too many open streams from ipv4:127.0.0.1");
  EXPECT_EQ(RetryAfter(fourth->context), "1000");
  // Unary calls are not streams: they still work.
  v1::Target target;
  EXPECT_TRUE(GetTarget(client, "bunny", &target).ok());
  for (auto& s : silent) s->context.TryCancel();
}

// Streams each opened on a thread of its own, sending a Register header and then nothing. (In
// gRPC's synchronous API a call blocks while it waits for a place on its connection, so each
// gets a thread; the destructor cancels them all.)
class SilentStreams {
 public:
  SilentStreams(const Client& client, const std::string& target_id, int count) {
    for (int i = 0; i < count; ++i) {
      streams_.push_back(std::make_unique<Stream>());
      client.Prepare(&streams_.back()->context, std::chrono::seconds(60));
    }
    for (int i = 0; i < count; ++i) {
      threads_.emplace_back([this, &client, target_id, stream = streams_[i].get()] {
        auto call = client.registration->Register(&stream->context);
        call->Write(HeaderOnlyRegister(target_id)[0]);
        const grpc::Status status = call->Finish();
        std::lock_guard<std::mutex> lock(mutex_);
        stream->status = status;
        stream->done = true;
      });
    }
  }
  ~SilentStreams() {
    for (auto& s : streams_) s->context.TryCancel();
    for (auto& t : threads_) t.join();
  }
  // Streams that ended RESOURCE_EXHAUSTED with `needle` in the message.
  int Refused(const std::string& needle) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(std::count_if(streams_.begin(), streams_.end(), [&](const auto& s) {
      return s->done && s->status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED &&
             s->status.error_message().find(needle) != std::string::npos;
    }));
  }
  int Ended() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(
        std::count_if(streams_.begin(), streams_.end(), [](const auto& s) { return s->done; }));
  }

 private:
  struct Stream {
    grpc::ClientContext context;
    grpc::Status status;
    bool done = false;
  };
  std::vector<std::unique_ptr<Stream>> streams_;
  std::vector<std::thread> threads_;
  mutable std::mutex mutex_;
};

// One bad client must not starve the others behind the same address (a NAT, a shared host):
// its streams are limited per connection (HTTP/2) and per token before the host's ceiling,
// which stays above them. A per-host limit alone refused the good client once the attacker
// held the host's streams.
TEST(AbuseTest, AnAttackerHoldingSilentStreamsDoesNotStarveAGoodClientOnTheSameHost) {
  ServerConfig config = TestConfig();
  config.token = "attacker-token\ngood-token";  // a token file of two lines: two clients
  config.max_streams_per_connection = 4;
  config.max_streams_per_client = 6;
  config.max_streams_per_peer = 10;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client good = ConnectOwn(server->port(), "good-token");
  ASSERT_TRUE(Upload(good, "bunny", Bun045()).ok());
  // 30 silent streams on one connection: 4 reach the server, the rest wait in the attacker's
  // own client for a place on its connection.
  const Client attacker = ConnectOwn(server->port(), "attacker-token");
  v1::Target target;
  ASSERT_TRUE(GetTarget(attacker, "bunny", &target).ok());  // connected: the limit is known
  auto on_one_connection = std::make_unique<SilentStreams>(attacker, "bunny", 30);
  ASSERT_TRUE(Eventually([&] { return server->open_streams() == 4; }, std::chrono::seconds(20)));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(server->open_streams(), 4);
  EXPECT_EQ(on_one_connection->Ended(), 0);
  ExpectServesOthers(good, "bunny");
  // More connections with the same token: its client's limit refuses what is beyond 6.
  const Client second = ConnectOwn(server->port(), "attacker-token");
  const Client third = ConnectOwn(server->port(), "attacker-token");
  ASSERT_TRUE(GetTarget(second, "bunny", &target).ok() && GetTarget(third, "bunny", &target).ok());
  SilentStreams more(second, "bunny", 4), still_more(third, "bunny", 4);
  ASSERT_TRUE(Eventually(
      [&] {
        return more.Refused("max_streams_per_client") +
                   still_more.Refused("max_streams_per_client") ==
               6;
      },
      std::chrono::seconds(20)));
  EXPECT_EQ(server->open_streams(), 6);
  // The good client, on its own connection from the same host, is still served: uploads,
  // lookups, health and registrations (streams of its own).
  ExpectServesOthers(good, "bunny");
  EXPECT_TRUE(Upload(good, "bunny-again", Prefix(Bun045(), 5000)).ok());
  on_one_connection.reset();  // the attacker gives up: every place is free again
  EXPECT_TRUE(Eventually([&] { return server->open_streams() == 2; }, std::chrono::seconds(10)));
}

TEST(AbuseTest, AStreamWhoseClientFallsSilentEndsAfterTheIdleTimeout) {
  ServerConfig config = TestConfig();
  config.idle_timeout_seconds = 0.3;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  {  // a registration whose source never comes
    auto s = OpenSilentRegister(client, HeaderOnlyRegister("bunny"), std::chrono::seconds(20));
    EXPECT_STATUS(s->stream->Finish(), grpc::StatusCode::DEADLINE_EXCEEDED,
                  "idle timeout: waited 0.3 s for a source chunk");
  }
  {  // an upload that stops after its first chunk
    grpc::ClientContext context;
    client.Prepare(&context, std::chrono::seconds(20));
    v1::Target out;
    auto writer = client.targets->CreateTarget(&context, &out);
    const auto messages = CreateMessages("stalled", Bun000(), 64 << 10);
    ASSERT_GT(messages.size(), 2u);
    writer->Write(messages[0]);
    writer->Write(messages[1]);
    EXPECT_STATUS(writer->Finish(), grpc::StatusCode::DEADLINE_EXCEEDED, "for a chunk");
  }
  // Their places and bytes are free again; nothing half-uploaded was kept.
  EXPECT_TRUE(
      Eventually([&] { return Stats(client).queue_depth() == 0; }, std::chrono::seconds(5)));
  v1::Target target;
  EXPECT_EQ(GetTarget(client, "stalled", &target).error_code(), grpc::StatusCode::NOT_FOUND);
  ExpectServesOthers(client, "bunny");
}

// ---- 4. in-flight data: budgeted from the header on, memory growing only with the data

TEST(AbuseTest, DeclaredCloudsCostNothingUntilTheirDataComesAndDataIsBudgeted) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  const std::uint64_t rss_before = ResidentBytes();
  // Six uploads that each declare 20 M points (960 MB in flight each) and send nothing more.
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientWriter<v1::CreateTargetRequest>>> writers;
  std::vector<v1::Target> outs(6);
  for (int i = 0; i < 6; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    client.Prepare(contexts.back().get(), std::chrono::seconds(30));
    writers.push_back(client.targets->CreateTarget(contexts.back().get(), &outs[i]));
    v1::CreateTargetRequest request;
    *request.mutable_header() = CloudHeaderOf("huge-" + std::to_string(i), 20'000'000);
    writers.back()->Write(request);
  }
  ASSERT_TRUE(Eventually([&] { return server->open_streams() == 6; }, std::chrono::seconds(20)));
  EXPECT_EQ(server->inflight_bytes(), 0u);               // declared, not sent: nothing held
  EXPECT_LT(ResidentBytes(), rss_before + (64u << 20));  // no buffer of the declared size
  ExpectServesOthers(client, "bunny");
  for (auto& writer : writers) {
    writer->WritesDone();
    EXPECT_STATUS(writer->Finish(), grpc::StatusCode::INVALID_ARGUMENT,
                  "ended after 0 of 480000000");
  }

  // Data that comes is budgeted: with 3 MiB in flight, an upload that has sent 1.2 MB of its
  // 2.9 MB (payload + decoded) leaves no room for a second such upload, refused from its header.
  ServerConfig small = TestConfig();
  small.max_inflight_bytes = 3 << 20;
  auto tight = StartServer(small);
  ASSERT_NE(tight, nullptr);
  const Client tight_client = Connect(tight->port());
  PointCloud cloud = Bun045();  // 60,000 points: 1.44 MB of float64 payload, as much decoded
  cloud.points.insert(cloud.points.end(), Bun000().points.begin(),
                      Bun000().points.begin() + (60'000 - Bun045().size()));
  grpc::ClientContext slow_context;
  tight_client.Prepare(&slow_context, std::chrono::seconds(30));
  v1::Target slow_out;
  auto slow = tight_client.targets->CreateTarget(&slow_context, &slow_out);
  const auto messages = CreateMessages("slow", cloud, 64 << 10);
  std::size_t sent = 0;
  for (std::size_t i = 0; i < messages.size() && sent < 1'200'000; ++i) {
    slow->Write(messages[i]);
    if (i > 0) sent += messages[i].chunk().data().size();
  }
  ASSERT_TRUE(
      Eventually([&] { return tight->inflight_bytes() >= 1'100'000; }, std::chrono::seconds(20)));
  std::string retry_after;
  v1::CreateTargetHeader second = messages[0].header();
  second.set_target_id("second");
  EXPECT_STATUS(CreateHeaderOnly(tight_client, second, &retry_after),
                grpc::StatusCode::RESOURCE_EXHAUSTED, "in-flight bytes (max_inflight_bytes)");
  EXPECT_EQ(retry_after, "200");  // transient: retry later
  // A request larger than the whole budget is refused for good.
  EXPECT_STATUS(CreateHeaderOnly(tight_client, CloudHeaderOf("big", 1'000'000), &retry_after),
                grpc::StatusCode::RESOURCE_EXHAUSTED,
                "more than the server's whole in-flight budget");
  EXPECT_EQ(retry_after, "-1");
  slow_context.TryCancel();
  slow->Finish();
  EXPECT_TRUE(Eventually([&] { return tight->inflight_bytes() == 0; }, std::chrono::seconds(5)));
}

// ---- 5. work that ignored cancellation: dense clusters, cancelled builds and registrations

PointCloud IdenticalPoints(std::size_t n) {
  PointCloud cloud;
  cloud.points.assign(n, Vec3(0.1, 0.2, 0.3));
  cloud.points.push_back(Vec3(1.0, 0.0, 0.0));
  cloud.points.push_back(Vec3(0.0, 1.0, 0.0));
  return cloud;
}

TEST(AbuseTest, DenseClustersCostBoundedWorkAndCancelledJobsFreeTheirWorker) {
  ServerConfig config = TestConfig();
  config.workers = 1;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  // As a target: the upload gives up after 0.5 s; its build must not keep the only worker.
  {
    grpc::ClientContext context;
    client.Prepare(&context, std::chrono::milliseconds(500));
    v1::Target out;
    auto writer = client.targets->CreateTarget(&context, &out);
    for (const auto& m : CreateMessages("cluster2", IdenticalPoints(40'000))) writer->Write(m);
    writer->WritesDone();
    writer->Finish();
  }
  EXPECT_TRUE(
      Eventually([&] { return Stats(client).active_jobs() == 0; }, std::chrono::seconds(3)));
  // As a source with 40k samples against a real target, with a 1 s deadline.
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  RegistrationOptions options = QuickOptions();
  options.num_samples = 40'000;
  options.max_iterations = 1000;
  const RegisterOutcome outcome =
      RunRegister(client,
                  RegisterMessages("bunny", IdenticalPoints(40'000), options, Matrix4::Identity(),
                                   {}, kMiB / 4),
                  std::chrono::seconds(1));
  EXPECT_NE(outcome.status.error_code(), grpc::StatusCode::INTERNAL)
      << outcome.status.error_message();
  EXPECT_TRUE(
      Eventually([&] { return Stats(client).active_jobs() == 0; }, std::chrono::seconds(3)));
  ExpectServesOthers(client, "bunny");
}

// ---- 6. stale results: content, not names, identifies a target

TEST(AbuseTest, OtherContentUnderATakenIdIsRefusedAndTheSameContentIsIdempotent) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client raw = Connect(server->port());
  client::ClientOptions options;
  options.address = "127.0.0.1:" + std::to_string(server->port());
  auto c = client::Client::Connect(options);
  ASSERT_TRUE(c.ok());
  auto first = (*c)->UploadTarget("scan", Bun045());
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(first->digest.rfind("sha256:", 0), 0u);
  auto again = (*c)->UploadTarget("scan", Bun045());
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(again->digest, first->digest);
  auto other = (*c)->UploadTarget("scan", Bun000());
  EXPECT_EQ(other.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_NE(other.status().message().find("other content"), std::string::npos);
  v1::Target target;
  ASSERT_TRUE(GetTarget(raw, "scan", &target).ok());
  EXPECT_EQ(target.point_count(), Bun045().size());  // the first upload is what is stored
  EXPECT_EQ(target.content_digest(), first->digest);
  // A digest that does not match the data is caught.
  auto messages = CreateMessages("liar", Bun000());
  messages[0].mutable_header()->set_content_digest(first->digest);
  EXPECT_STATUS(SendCreate(raw, messages), grpc::StatusCode::INVALID_ARGUMENT,
                "header.content_digest: declared");
  // A declared digest must have the form the server writes, whatever its length.
  for (const std::string& bad : {std::string("sha256:xyz"), "sha256:" + std::string(10000, 'a'),
                                 "md5:" + std::string(64, '0')}) {
    messages[0].mutable_header()->set_content_digest(bad);
    EXPECT_STATUS(SendCreate(raw, messages), grpc::StatusCode::INVALID_ARGUMENT,
                  "header.content_digest: must be");
  }
}

// ---- 7. retries that cannot help

TEST(AbuseTest, ATargetLargerThanTheCacheIsNotRetried) {
  ServerConfig config = TestConfig();
  config.cache_budget_bytes = 1 << 20;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  client::ClientOptions options;
  options.address = "127.0.0.1:" + std::to_string(server->port());
  options.initial_backoff_seconds = 0.01;
  auto c = client::Client::Connect(options);
  ASSERT_TRUE(c.ok());
  auto uploaded = (*c)->UploadTarget("big", Bun045());
  EXPECT_EQ(uploaded.status().code(), absl::StatusCode::kResourceExhausted);
  const v1::GetStatsResponse stats = Stats(Connect(server->port()));
  std::uint64_t attempts = 0;
  for (const auto& r : stats.requests()) {
    if (r.rpc() == "CreateTarget") attempts += r.count();
  }
  EXPECT_EQ(attempts, 1u);  // once, not max_attempts times with the whole cloud each
}

// ---- 9. smaller ones

TEST(AbuseTest, ACacheKeepsCountingADeletedTargetWhileARegistrationUsesIt) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  const std::uint64_t bytes = Stats(client).cache_bytes();
  RegisterCall call(client,
                    RegisterMessages("bunny", Bun000(), EndlessOptions(), PerturbedStart(5, 5, 1)));
  ASSERT_TRUE(call.WaitForProgress(1));
  grpc::ClientContext context;
  client.Prepare(&context);
  v1::DeleteTargetRequest request;
  request.set_target_id("bunny");
  v1::DeleteTargetResponse response;
  ASSERT_TRUE(client.targets->DeleteTarget(&context, request, &response).ok());
  EXPECT_EQ(Stats(client).cache_bytes(), bytes);  // still in memory under the registration
  call.Cancel();
  call.Join();
  EXPECT_TRUE(
      Eventually([&] { return Stats(client).cache_bytes() == 0; }, std::chrono::seconds(5)));
}

TEST(AbuseTest, ReverseCalibrationWithoutADepthImageIsRefusedBeforeAdmission) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  RegistrationOptions options = QuickOptions();
  options.method = Method::kRcBl;
  const RegisterOutcome outcome =
      RunRegister(client, RegisterMessages("bunny", Bun000(), options, Matrix4::Identity()));
  EXPECT_STATUS(outcome.status, grpc::StatusCode::FAILED_PRECONDITION, "needs an organised target");
  EXPECT_EQ(outcome.accepted(), nullptr);
}

TEST(AbuseTest, HugeCoordinatesAreRefusedNamingTheCause) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  PointCloud cloud = Prefix(Bun045(), 100);
  cloud.points[7] = Vec3(1e200, 0, 0);
  EXPECT_STATUS(Upload(client, "far", cloud), grpc::StatusCode::INVALID_ARGUMENT,
                "point 7 has a coordinate of magnitude 1e+200");
  ASSERT_TRUE(Upload(client, "bunny", Bun045()).ok());
  const RegisterOutcome outcome =
      RunRegister(client, RegisterMessages("bunny", cloud, QuickOptions(), Matrix4::Identity()));
  EXPECT_STATUS(outcome.status, grpc::StatusCode::INVALID_ARGUMENT, "source: point 7");
  ExpectServesOthers(client, "bunny");
}

TEST(AbuseTest, FilesThatAreNotTargetsInTheDataDirectoryDoNotBreakListing) {
  const fs::path dir = fs::temp_directory_path() / ("mlsreg-abuse-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ServerConfig config = TestConfig();
  config.data_dir = dir.string();
  {
    auto server = StartServer(config);
    ASSERT_NE(server, nullptr);
    const Client client = Connect(server->port());
    ASSERT_TRUE(Upload(client, "a", Prefix(Bun045(), 500)).ok());
    ASSERT_TRUE(Upload(client, "b", Prefix(Bun045(), 600)).ok());
  }
  for (const char* name : {"not an id.ply", ".hidden.ply", "x;y.ply"}) {
    fs::copy_file(dir / "targets" / "a.ply", dir / "targets" / name);
  }
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  std::vector<std::string> ids;
  std::string token;
  do {
    grpc::ClientContext context;
    client.Prepare(&context);
    v1::ListTargetsRequest request;
    request.set_page_size(1);
    request.set_page_token(token);
    v1::ListTargetsResponse response;
    const grpc::Status status = client.targets->ListTargets(&context, request, &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    for (const auto& t : response.targets()) ids.push_back(t.target_id());
    token = response.next_page_token();
  } while (!token.empty() && ids.size() < 10);
  EXPECT_EQ(ids, (std::vector<std::string>{"a", "b"}));
  fs::remove_all(dir);
}

TEST(AbuseTest, ATokenReadFromAFileIsRequired) {
  const fs::path file = fs::temp_directory_path() / ("mlsreg-token-" + std::to_string(::getpid()));
  std::ofstream(file) << "s3cret-from-file\n";
  ServerConfig config = TestConfig();
  config.token_file = file.string();
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  v1::Target target;
  EXPECT_EQ(GetTarget(Connect(server->port()), "x", &target).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(GetTarget(Connect(server->port(), "s3cret-from-file"), "x", &target).error_code(),
            grpc::StatusCode::NOT_FOUND);
  fs::remove(file);
}

}  // namespace
}  // namespace mlsreg::service_test
