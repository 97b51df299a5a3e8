#include "service_test_support.h"

#include <gtest/gtest.h>

#include "mlsreg/core/transform.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg::service_test {
namespace {

const std::string kBunnyDir = std::string(MLSREG_SOURCE_DIR) + "/data/bunny/";

PointCloud MustRead(const std::string& path) {
  auto cloud = ReadPointCloud(path);
  if (!cloud.ok()) {
    ADD_FAILURE() << cloud.status();
    return PointCloud{};
  }
  return *std::move(cloud);
}

}  // namespace

const PointCloud& Bun000() {
  static const PointCloud cloud = MustRead(kBunnyDir + "bun000.ply");
  return cloud;
}

const PointCloud& Bun045() {
  static const PointCloud cloud = MustRead(kBunnyDir + "bun045.ply");
  return cloud;
}

const Matrix4& Bun000ToBun045() {
  static const Matrix4 truth = [] {
    auto manifest = ReadManifest(kBunnyDir + "pairs.csv");
    if (manifest.ok()) {
      for (const ManifestProblem& p : manifest->problems) {
        if (p.id == "bun000_bun045" && p.ground_truth) return *p.ground_truth;
      }
    }
    ADD_FAILURE() << "bun000_bun045 not found in pairs.csv";
    return Matrix4(Matrix4::Identity());
  }();
  return truth;
}

const std::shared_ptr<const Target>& Bun045Target() {
  static const std::shared_ptr<const Target> target = [] {
    auto built = Target::Build(Bun045());
    if (!built.ok()) ADD_FAILURE() << built.status();
    return built.ok() ? *built : nullptr;
  }();
  return target;
}

Matrix4 PerturbedStart(double angle_deg, double distance_d, std::uint64_t seed) {
  const Matrix4& truth = Bun000ToBun045();
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : Bun000().points) centroid += p;
  centroid /= static_cast<double>(Bun000().size());
  const Vec3 moved = truth.topLeftCorner<3, 3>() * centroid + truth.topRightCorner<3, 1>();
  const double d = Bun045Target()->sampling_distance();
  return RandomPerturbation(angle_deg, distance_d * d, moved, seed) * truth;
}

PointCloud Prefix(const PointCloud& cloud, std::size_t n) {
  PointCloud out;
  out.points.assign(cloud.points.begin(), cloud.points.begin() + std::min(n, cloud.size()));
  return out;
}

ServerConfig TestConfig() {
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.workers = 2;
  config.drain_seconds = 2;
  return config;
}

std::unique_ptr<MlsregServer> StartServer(const ServerConfig& config) {
  auto server = MlsregServer::Start(config);
  if (!server.ok()) {
    ADD_FAILURE() << "server did not start: " << server.status();
    return nullptr;
  }
  return *std::move(server);
}

void Client::Prepare(grpc::ClientContext* context, std::chrono::milliseconds timeout) const {
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
  context->set_deadline(std::chrono::system_clock::now() + timeout);
}

Client Connect(std::shared_ptr<grpc::Channel> channel, std::string token) {
  Client c;
  c.channel = std::move(channel);
  c.targets = v1::TargetService::NewStub(c.channel);
  c.registration = v1::RegistrationService::NewStub(c.channel);
  c.stats = v1::StatsService::NewStub(c.channel);
  c.token = std::move(token);
  return c;
}

Client Connect(int port, std::string token) {
  return Connect(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()),
      std::move(token));
}

Client ConnectOwn(int port, std::string token) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return Connect(grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port),
                                           grpc::InsecureChannelCredentials(), args),
                 std::move(token));
}

namespace {

std::vector<v1::CreateTargetRequest> CreateMessagesOf(const std::string& id,
                                                      const PointCloud& cloud,
                                                      std::size_t chunk_bytes,
                                                      v1::ScalarType scalar_type) {
  std::vector<v1::CreateTargetRequest> messages(1);
  v1::CreateTargetHeader* header = messages[0].mutable_header();
  header->set_target_id(id);
  std::string payload;
  wire::EncodeCloud(cloud, scalar_type, header->mutable_cloud(), &payload);
  wire::WriteChunks(payload, chunk_bytes, [&](const v1::CloudChunk& chunk) {
    *messages.emplace_back().mutable_chunk() = chunk;
    return true;
  });
  return messages;
}

}  // namespace

std::vector<v1::CreateTargetRequest> CreateMessages(const std::string& id, const PointCloud& cloud,
                                                    std::size_t chunk_bytes) {
  return CreateMessagesOf(id, cloud, chunk_bytes, v1::SCALAR_TYPE_FLOAT64);
}

grpc::Status SendCreate(const Client& client, const std::vector<v1::CreateTargetRequest>& messages,
                        v1::Target* out) {
  grpc::ClientContext context;
  client.Prepare(&context);
  v1::Target response;
  auto writer = client.targets->CreateTarget(&context, &response);
  for (const auto& m : messages) {
    if (!writer->Write(m)) break;  // the server answered early; Finish tells why
  }
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  if (out) *out = response;
  return status;
}

grpc::Status Upload(const Client& client, const std::string& id, const PointCloud& cloud,
                    v1::Target* out, std::size_t chunk_bytes, v1::ScalarType scalar_type) {
  return SendCreate(client, CreateMessagesOf(id, cloud, chunk_bytes, scalar_type), out);
}

grpc::Status GetTarget(const Client& client, const std::string& id, v1::Target* out) {
  grpc::ClientContext context;
  client.Prepare(&context);
  v1::GetTargetRequest request;
  request.set_target_id(id);
  return client.targets->GetTarget(&context, request, out);
}

v1::GetStatsResponse Stats(const Client& client) {
  grpc::ClientContext context;
  client.Prepare(&context);
  v1::GetStatsResponse response;
  const grpc::Status status = client.stats->GetStats(&context, {}, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  return response;
}

RegistrationOptions QuickOptions() {
  RegistrationOptions options;
  options.method = Method::kMlsSicp;  // one ICP loop: iteration counts are exact
  options.num_samples = 500;
  options.max_iterations = 30;
  return options;
}

RegistrationOptions EndlessOptions() {
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  options.num_samples = 2000;
  options.max_iterations = 100'000;
  options.convergence_d = 0.0;  // nothing ever moves less than 0: never converges
  options.coarse_convergence_d = 0.0;
  options.stall_d = 0.0;
  options.stall_noise_fraction = 0.0;
  options.stall_standard_errors = 0.0;
  return options;
}

std::vector<v1::RegisterRequest> RegisterMessages(
    const std::string& target_id, const PointCloud& source, const RegistrationOptions& options,
    const Matrix4& initial, const std::optional<Matrix4>& ground_truth, std::size_t chunk_bytes) {
  std::vector<v1::RegisterRequest> messages(1);
  v1::RegisterHeader* header = messages[0].mutable_header();
  std::string payload;
  wire::BuildRegisterHeader(target_id, source, v1::SCALAR_TYPE_FLOAT64, options, initial,
                            ground_truth, header, &payload);
  if (chunk_bytes == 0) {
    header->set_source_data(std::move(payload));
    return messages;
  }
  wire::WriteChunks(payload, chunk_bytes, [&](const v1::CloudChunk& chunk) {
    *messages.emplace_back().mutable_source_chunk() = chunk;
    return true;
  });
  return messages;
}

int RegisterOutcome::progress_count() const { return static_cast<int>(progress().size()); }

const v1::Accepted* RegisterOutcome::accepted() const {
  for (const auto& r : responses) {
    if (r.has_accepted()) return &r.accepted();
  }
  return nullptr;
}

const v1::Result* RegisterOutcome::result() const {
  for (const auto& r : responses) {
    if (r.has_result()) return &r.result();
  }
  return nullptr;
}

std::vector<const v1::Progress*> RegisterOutcome::progress() const {
  std::vector<const v1::Progress*> out;
  for (const auto& r : responses) {
    if (r.has_progress()) out.push_back(&r.progress());
  }
  return out;
}

RegisterCall::RegisterCall(const Client& client, std::vector<v1::RegisterRequest> messages,
                           std::chrono::milliseconds timeout)
    : client_(client) {
  client_.Prepare(&context_, timeout);
  thread_ = std::thread([this, m = std::move(messages)]() mutable { Run(std::move(m)); });
}

RegisterCall::~RegisterCall() {
  if (thread_.joinable()) {
    Cancel();
    thread_.join();
  }
}

void RegisterCall::Run(std::vector<v1::RegisterRequest> messages) {
  auto stream = client_.registration->Register(&context_);
  for (const auto& m : messages) {
    if (!stream->Write(m)) break;
  }
  stream->WritesDone();
  v1::RegisterResponse response;
  while (stream->Read(&response)) {
    std::lock_guard<std::mutex> lock(mutex_);
    outcome_.responses.push_back(response);
    changed_.notify_all();
  }
  grpc::Status status = stream->Finish();
  std::lock_guard<std::mutex> lock(mutex_);
  outcome_.status = std::move(status);
  finished_ = true;
  changed_.notify_all();
}

bool RegisterCall::WaitFor(const std::function<bool()>& ready, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait_for(lock, timeout, [&] { return ready() || finished_; });
  return ready();
}

bool RegisterCall::WaitForAccepted(std::chrono::milliseconds timeout) {
  return WaitFor([this] { return outcome_.accepted() != nullptr; }, timeout);
}

bool RegisterCall::WaitForProgress(int count, std::chrono::milliseconds timeout) {
  return WaitFor([this, count] { return outcome_.progress_count() >= count; }, timeout);
}

RegisterOutcome RegisterCall::Join() {
  if (thread_.joinable()) thread_.join();
  return outcome_;
}

RegisterOutcome RunRegister(const Client& client, const std::vector<v1::RegisterRequest>& messages,
                            std::chrono::milliseconds timeout) {
  RegisterCall call(client, messages, timeout);
  return call.Join();
}

bool Eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

}  // namespace mlsreg::service_test
