// RegistrationService.AlignScans over a real channel: uploaded and cached scans give the
// library's poses, every edge streams, every malformed header is refused naming its field while
// the server goes on serving, the in-flight budget refuses uploads before their data, and a
// client that cancels frees the worker.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "mlsreg/client/client.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/wire/align_codec.h"
#include "mlsreg/wire/convert.h"
#include "server/align_scans_call.h"
#include "service_test_support.h"

namespace mlsreg::service_test {
namespace {

// Scans [bun045, bun000]: the true poses are identity and bun000 -> bun045.
std::vector<Matrix4> TruePoses() { return {Matrix4::Identity(), Bun000ToBun045()}; }

AlignOptions QuickAlign() {
  AlignOptions options;
  options.pairs = PairPolicy::kSequential;
  options.initial_poses = {Matrix4::Identity(), PerturbedStart(5.0, 5.0, 7)};
  options.edge.num_samples = 500;
  options.edge.max_iterations = 30;
  return options;
}

double RotationErrorDeg(const Matrix4& a, const Matrix4& b) {
  const Eigen::AngleAxisd aa(
      Eigen::Matrix3d(a.topLeftCorner<3, 3>().transpose() * b.topLeftCorner<3, 3>()));
  return std::abs(aa.angle()) * 180.0 / M_PI;
}

// The header of a call over these scans: a cached id, or (null id) a cloud sent after it.
struct Scan {
  std::string target_id;
  const PointCloud* cloud = nullptr;
};
std::vector<v1::AlignScansRequest> AlignMessages(const std::vector<Scan>& scans,
                                                 const AlignOptions& options,
                                                 std::size_t chunk_bytes = kMiB) {
  std::vector<v1::AlignScansRequest> messages(1);
  v1::AlignScansHeader* header = messages[0].mutable_header();
  wire::AlignOptionsToProto(options, header);
  std::string payload;
  for (const Scan& scan : scans) {
    v1::AlignScan* out = header->add_scans();
    if (!scan.target_id.empty()) {
      out->set_target_id(scan.target_id);
      continue;
    }
    std::string data;
    wire::EncodeCloud(*scan.cloud, v1::SCALAR_TYPE_FLOAT64, out->mutable_cloud(), &data);
    payload += data;
  }
  wire::WriteChunks(payload, chunk_bytes, [&](const v1::CloudChunk& chunk) {
    *messages.emplace_back().mutable_scan_chunk() = chunk;
    return true;
  });
  return messages;
}

struct AlignCallOutcome {
  grpc::Status status;
  std::vector<v1::AlignScansResponse> responses;
};

AlignCallOutcome RunAlign(const Client& client,
                          const std::vector<v1::AlignScansRequest>& messages) {
  grpc::ClientContext context;
  client.Prepare(&context);
  auto stream = client.registration->AlignScans(&context);
  for (const v1::AlignScansRequest& m : messages) {
    if (!stream->Write(m)) break;
  }
  stream->WritesDone();
  AlignCallOutcome outcome;
  v1::AlignScansResponse response;
  while (stream->Read(&response)) outcome.responses.push_back(response);
  outcome.status = stream->Finish();
  return outcome;
}

class AlignScansServiceTest : public ::testing::Test {
 protected:
  void StartWith(ServerConfig config) {
    server_ = StartServer(config);
    ASSERT_NE(server_, nullptr);
    raw_ = Connect(server_->port());
    client::ClientOptions options;
    options.address = "127.0.0.1:" + std::to_string(server_->port());
    options.max_attempts = 1;
    auto c = client::Client::Connect(options);
    ASSERT_TRUE(c.ok()) << c.status();
    client_ = *std::move(c);
  }
  // A good alignment still runs, and nothing is left held.
  void ExpectServesOthers() {
    auto good = client_->AlignScans({{"", std::make_shared<PointCloud>(Bun045())},
                                     {"", std::make_shared<PointCloud>(Bun000())}},
                                    QuickAlign());
    EXPECT_TRUE(good.ok()) << good.status();
    EXPECT_TRUE(
        Eventually([&] { return server_->inflight_bytes() == 0 && Stats(raw_).active_jobs() == 0; },
                   std::chrono::seconds(5)));
  }

  std::unique_ptr<MlsregServer> server_;
  Client raw_;
  std::unique_ptr<client::Client> client_;
};

// The overlap distance crosses the wire in the unit it was given in.
TEST(AlignCodecTest, TheOverlapDistanceKeepsItsUnit) {
  for (const GivenLength length : {GivenLength{12.5, false}, GivenLength{4.0, true}}) {
    AlignOptions options;
    options.overlap_distance = length;
    v1::AlignScansHeader header;
    wire::AlignOptionsToProto(options, &header);
    EXPECT_EQ(header.has_overlap_distance(), length.absolute);
    EXPECT_EQ(header.has_overlap_distance_d(), !length.absolute);
    auto back = wire::AlignOptionsFromProto(header);
    ASSERT_TRUE(back.ok()) << back.status();
    EXPECT_EQ(back->overlap_distance.value, length.value);
    EXPECT_EQ(back->overlap_distance.absolute, length.absolute);
  }
}

// A header that names no method gets the library's (and the CLI's) default edges: auto.
TEST(AlignCodecTest, AnUnspecifiedMethodIsAuto) {
  v1::AlignScansHeader header;
  auto options = wire::AlignOptionsFromProto(header);
  ASSERT_TRUE(options.ok()) << options.status();
  EXPECT_EQ(options->edge.method, Method::kAuto);
  EXPECT_EQ(options->edge.method, AlignOptions().edge.method);
  header.set_method(v1::METHOD_MLS_SICP);
  EXPECT_EQ(wire::AlignOptionsFromProto(header)->edge.method, Method::kMlsSicp);
}

TEST_F(AlignScansServiceTest, UploadedScansGiveTheLibrarysPosesAndEveryEdgeStreams) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  const AlignOptions options = QuickAlign();
  std::vector<std::tuple<int, int, int, int>> streamed;  // from, to, done, total
  auto served = client_->AlignScans(
      {{"", std::make_shared<PointCloud>(Bun045())}, {"", std::make_shared<PointCloud>(Bun000())}},
      options, [&](const AlignEdge& e, int done, int total) {
        streamed.emplace_back(e.from, e.to, done, total);
      });
  ASSERT_TRUE(served.ok()) << served.status();
  AlignOptions local_options = options;
  local_options.threads = TestConfig().job_threads;
  auto local = AlignScans({Bun045(), Bun000()}, local_options);
  ASSERT_TRUE(local.ok()) << local.status();

  ASSERT_EQ(streamed.size(), 1u);
  EXPECT_EQ(streamed[0], std::make_tuple(0, 1, 1, 1));
  const AlignResult& result = served->result;
  ASSERT_EQ(result.poses.size(), 2u);
  ASSERT_EQ(result.edges.size(), 1u);
  EXPECT_TRUE(result.poses[0] == Matrix4::Identity());
  EXPECT_LT((result.poses[1] - local->poses[1]).cwiseAbs().maxCoeff(), 1e-12);
  // The second scan's pose covariance crosses the wire as the library computed it, to the
  // rounding that separates the two poses (they agree to 1e-12, not bit for bit, on every CPU).
  ASSERT_EQ(result.pose_covariances.size(), 2u);
  EXPECT_FALSE(result.pose_covariances[0].has_value());
  ASSERT_TRUE(result.pose_covariances[1] && local->pose_covariances[1]);
  const Matrix6& local_covariance = *local->pose_covariances[1];
  EXPECT_GT(local_covariance.norm(), 0.0);
  EXPECT_LT((*result.pose_covariances[1] - local_covariance).norm(),
            1e-9 * local_covariance.norm());
  EXPECT_EQ(result.edges[0].registration.iterations, local->edges[0].registration.iterations);
  EXPECT_NEAR(result.edges[0].overlap, local->edges[0].overlap, 1e-12);
  // And it is right: bun000 onto bun045 within 1 degree and 2 d of the scanner's poses (good to
  // about 0.5 d, data/bunny/SOURCE.md), from a 5 degree / 5 d start.
  const double d = Bun045Target()->sampling_distance();
  EXPECT_LT(RotationErrorDeg(result.poses[1], TruePoses()[1]), 1.0);
  EXPECT_LT((result.poses[1].topRightCorner<3, 1>() - TruePoses()[1].topRightCorner<3, 1>()).norm(),
            2.0 * d);
  EXPECT_TRUE(Eventually([&] { return server_->inflight_bytes() == 0; }, std::chrono::seconds(5)));
}

TEST_F(AlignScansServiceTest, CachedScansAlignLikeUploadedOnes) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  ASSERT_TRUE(Upload(raw_, "bun045", Bun045()).ok());
  ASSERT_TRUE(Upload(raw_, "bun000", Bun000()).ok());
  const AlignOptions options = QuickAlign();
  auto uploaded = client_->AlignScans(
      {{"", std::make_shared<PointCloud>(Bun045())}, {"", std::make_shared<PointCloud>(Bun000())}},
      options);
  auto cached = client_->AlignScans({{"bun045", nullptr}, {"bun000", nullptr}}, options);
  auto mixed = client_->AlignScans(
      {{"bun045", nullptr}, {"", std::make_shared<PointCloud>(Bun000())}}, options);
  ASSERT_TRUE(uploaded.ok()) << uploaded.status();
  ASSERT_TRUE(cached.ok()) << cached.status();
  ASSERT_TRUE(mixed.ok()) << mixed.status();
  EXPECT_LT((cached->result.poses[1] - uploaded->result.poses[1]).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((mixed->result.poses[1] - uploaded->result.poses[1]).cwiseAbs().maxCoeff(), 1e-9);
  // The cached targets stay cached, unchanged.
  v1::Target target;
  ASSERT_TRUE(GetTarget(raw_, "bun000", &target).ok());
  EXPECT_EQ(target.point_count(), Bun000().size());
}

TEST_F(AlignScansServiceTest, MalformedHeadersAreRefusedNamingTheFieldAndOthersGoOn) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  ASSERT_TRUE(Upload(raw_, "bun045", Bun045()).ok());
  const PointCloud tiny = Prefix(Bun000(), 5);
  AlignOptions options = QuickAlign();
  const auto cached_pair = [&] { return AlignMessages({{"bun045"}, {"", &Bun000()}}, options); };
  struct Case {
    std::string name;
    std::vector<v1::AlignScansRequest> messages;
    grpc::StatusCode code;
    std::string needle;
  };
  std::vector<Case> cases;
  {
    AlignOptions one = options;
    one.initial_poses.clear();
    cases.push_back({"a single scan", AlignMessages({{"bun045"}}, one),
                     grpc::StatusCode::INVALID_ARGUMENT,
                     "header.scans: need 2 to 100 scans, got 1"});
  }
  {
    AlignOptions many = options;
    many.initial_poses.clear();
    std::vector<Scan> scans;
    for (int i = 0; i <= server::kMaxAlignScans; ++i) scans.push_back({absl::StrCat("s", i)});
    cases.push_back({"101 scans", AlignMessages(scans, many), grpc::StatusCode::INVALID_ARGUMENT,
                     "need 2 to 100 scans, got 101"});
  }
  cases.push_back({"an unknown target", AlignMessages({{"bun045"}, {"nope"}}, options),
                   grpc::StatusCode::NOT_FOUND, "header.scans[1].target_id"});
  cases.push_back({"a target twice", AlignMessages({{"bun045"}, {"bun045"}}, options),
                   grpc::StatusCode::INVALID_ARGUMENT, "is given twice"});
  {
    AlignOptions three = options;
    three.initial_poses.push_back(Matrix4::Identity());
    cases.push_back({"3 poses for 2 scans", AlignMessages({{"bun045"}, {"", &Bun000()}}, three),
                     grpc::StatusCode::INVALID_ARGUMENT, "initial_poses"});
  }
  {
    auto messages = cached_pair();
    messages[0].mutable_header()->mutable_initial_poses(1)->set_row_major(0, 2.0);
    cases.push_back(
        {"a non-rigid pose", messages, grpc::StatusCode::INVALID_ARGUMENT, "initial_poses[1]"});
  }
  {
    auto messages = cached_pair();
    messages[0].mutable_header()->set_overlap_distance(-2.0);
    cases.push_back({"a negative overlap distance in the clouds' units", messages,
                     grpc::StatusCode::INVALID_ARGUMENT,
                     "overlap_distance: must be a positive length"});
  }
  {
    auto messages = cached_pair();
    messages[0].mutable_header()->set_anchor(5);
    cases.push_back({"an anchor out of range", messages, grpc::StatusCode::INVALID_ARGUMENT,
                     "anchor: 5 is not a scan index"});
  }
  {
    auto messages = cached_pair();
    messages[0].mutable_header()->mutable_scans(1)->Clear();
    cases.push_back({"a scan with neither id nor cloud", messages,
                     grpc::StatusCode::INVALID_ARGUMENT, "header.scans[1]: set target_id"});
  }
  cases.push_back({"a 5-point scan", AlignMessages({{"bun045"}, {"", &tiny}}, options),
                   grpc::StatusCode::INVALID_ARGUMENT, "header.scans[1].cloud.point_count"});
  {
    auto messages = cached_pair();
    messages.erase(messages.begin());
    cases.push_back({"a chunk first", messages, grpc::StatusCode::INVALID_ARGUMENT,
                     "header: the first message must be the header"});
  }
  {
    auto messages = AlignMessages({{"bun045"}, {"", &Bun000()}}, options, 64 << 10);
    messages.resize(2);  // the header and the first 64 KiB of the data
    cases.push_back(
        {"data that ends early", messages, grpc::StatusCode::INVALID_ARGUMENT, "scan_chunk"});
  }
  {
    // Scan 1 a kilometre away: no pair overlaps under the initial poses. Found on the worker.
    AlignOptions apart = options;
    apart.pairs = PairPolicy::kOverlap;
    apart.initial_poses[1](0, 3) += 1000.0;
    cases.push_back({"a disconnected pair graph",
                     AlignMessages({{"bun045"}, {"", &Bun000()}}, apart),
                     grpc::StatusCode::INVALID_ARGUMENT, "pairs: the pair graph (overlap)"});
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const AlignCallOutcome outcome = RunAlign(raw_, c.messages);
    EXPECT_STATUS(outcome.status, c.code, c.needle);
    for (const v1::AlignScansResponse& r : outcome.responses) EXPECT_FALSE(r.has_result());
  }
  ExpectServesOthers();
}

TEST_F(AlignScansServiceTest, UploadsBeyondTheInFlightBudgetAreRefusedBeforeTheirData) {
  ServerConfig config = TestConfig();
  config.max_inflight_bytes = 3 << 20;  // less than two uploaded bunny scans and their targets
  ASSERT_NO_FATAL_FAILURE(StartWith(config));
  auto messages = AlignMessages({{"", &Bun045()}, {"", &Bun000()}}, QuickAlign());
  messages.resize(1);  // the header alone: refused before any data is sent
  const AlignCallOutcome outcome = RunAlign(raw_, messages);
  EXPECT_STATUS(outcome.status, grpc::StatusCode::RESOURCE_EXHAUSTED, "header.scans");
  EXPECT_NE(outcome.status.error_message().find("max_inflight_bytes"), std::string::npos);
  EXPECT_TRUE(outcome.responses.empty());
  EXPECT_EQ(server_->inflight_bytes(), 0u);
  // Cached scans cost nothing in flight: the same alignment over them runs.
  ASSERT_TRUE(Upload(raw_, "bun045", Bun045()).ok());
  ASSERT_TRUE(Upload(raw_, "bun000", Bun000()).ok());
  auto cached = client_->AlignScans({{"bun045", nullptr}, {"bun000", nullptr}}, QuickAlign());
  EXPECT_TRUE(cached.ok()) << cached.status();
}

TEST_F(AlignScansServiceTest, CancellingTheCallCancelsTheJobAtOnce) {
  ASSERT_NO_FATAL_FAILURE(StartWith(TestConfig()));
  ASSERT_TRUE(Upload(raw_, "bun045", Bun045()).ok());
  ASSERT_TRUE(Upload(raw_, "bun000", Bun000()).ok());
  AlignOptions endless = QuickAlign();
  endless.edge = EndlessOptions();
  endless.edge.method = Method::kMlsSicp;
  grpc::ClientContext context;
  raw_.Prepare(&context);
  auto stream = raw_.registration->AlignScans(&context);
  ASSERT_TRUE(stream->Write(AlignMessages({{"bun045"}, {"bun000"}}, endless)[0]));
  v1::AlignScansResponse response;
  ASSERT_TRUE(stream->Read(&response));
  EXPECT_TRUE(response.has_accepted());
  ASSERT_TRUE(Eventually([&] { return Stats(raw_).active_jobs() == 1; }, std::chrono::seconds(20)));
  context.TryCancel();
  while (stream->Read(&response)) EXPECT_FALSE(response.has_result());
  EXPECT_EQ(stream->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_TRUE(Eventually([&] { return Stats(raw_).active_jobs() == 0; }, std::chrono::seconds(2)));

  // The client library's cancel flag does the same.
  std::atomic<bool> cancel{false};
  std::thread canceller([&] {
    Eventually([&] { return Stats(raw_).active_jobs() == 1; }, std::chrono::seconds(20));
    cancel = true;
  });
  auto cancelled =
      client_->AlignScans({{"bun045", nullptr}, {"bun000", nullptr}}, endless, {}, &cancel);
  canceller.join();
  EXPECT_EQ(cancelled.status().code(), absl::StatusCode::kCancelled) << cancelled.status();
  EXPECT_TRUE(Eventually([&] { return Stats(raw_).active_jobs() == 0; }, std::chrono::seconds(2)));
  ExpectServesOthers();
}

}  // namespace
}  // namespace mlsreg::service_test
