// Helpers for the service tests: the real MlsregServer started in-process on 127.0.0.1:0 and
// spoken to through the generated stubs over a real channel.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "server/server.h"

// A gRPC status with this code whose message contains `needle` (a field name, a limit).
#define EXPECT_STATUS(status, expected_code, needle)                                     \
  do {                                                                                   \
    const grpc::Status s_ = (status);                                                    \
    EXPECT_EQ(s_.error_code(), expected_code) << s_.error_message();                     \
    EXPECT_NE(s_.error_message().find(needle), std::string::npos) << s_.error_message(); \
  } while (0)

namespace mlsreg::service_test {

namespace v1 = ::mlsreg::v1;
using server::MlsregServer;
using server::ServerConfig;

inline constexpr std::size_t kMiB = 1 << 20;

// ---- data (loaded once per process)
const PointCloud& Bun000();
const PointCloud& Bun045();
// bun000 -> bun045 from data/bunny/pairs.csv.
const Matrix4& Bun000ToBun045();
// The target built in-process from bun045 (for d and the reference registrations).
const std::shared_ptr<const Target>& Bun045Target();
// The start pose of the tests: the ground truth perturbed by `angle_deg` and `distance_d` * d
// about the centroid of bun000 under the ground truth.
Matrix4 PerturbedStart(double angle_deg, double distance_d, std::uint64_t seed);
// The first n points of a cloud (a cheap small cloud).
PointCloud Prefix(const PointCloud& cloud, std::size_t n);

// ---- server and client
// A config for tests: loopback port 0, 2 workers.
ServerConfig TestConfig();
// Starts the server; records a test failure and returns null when it does not start.
std::unique_ptr<MlsregServer> StartServer(const ServerConfig& config);

struct Client {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::TargetService::Stub> targets;
  std::unique_ptr<v1::RegistrationService::Stub> registration;
  std::unique_ptr<v1::StatsService::Stub> stats;
  std::string token;  // sent as "authorization: Bearer <token>" when not empty

  // Adds the token and a deadline (so a broken server fails a test instead of hanging it).
  void Prepare(grpc::ClientContext* context,
               std::chrono::milliseconds timeout = std::chrono::seconds(60)) const;
};
Client Connect(std::shared_ptr<grpc::Channel> channel, std::string token = "");
Client Connect(int port, std::string token = "");
// A client on a TCP connection of its own (channels to the same address otherwise share one).
Client ConnectOwn(int port, std::string token = "");

// ---- targets
// CreateTarget with the header and the payload cut into `chunk_bytes` chunks.
grpc::Status Upload(const Client& client, const std::string& id, const PointCloud& cloud,
                    v1::Target* out = nullptr, std::size_t chunk_bytes = kMiB,
                    v1::ScalarType scalar_type = v1::SCALAR_TYPE_FLOAT64);
// CreateTarget with exactly these messages (for malformed uploads).
grpc::Status SendCreate(const Client& client, const std::vector<v1::CreateTargetRequest>& messages,
                        v1::Target* out = nullptr);
std::vector<v1::CreateTargetRequest> CreateMessages(const std::string& id, const PointCloud& cloud,
                                                    std::size_t chunk_bytes = kMiB);
grpc::Status GetTarget(const Client& client, const std::string& id, v1::Target* out);
v1::GetStatsResponse Stats(const Client& client);

// ---- registrations
// Options for quick registrations (500 samples, at most 30 iterations).
RegistrationOptions QuickOptions();
// Options for a registration that never converges (it runs until cancelled).
RegistrationOptions EndlessOptions();

// The messages of a Register call: header (+ source chunks of `chunk_bytes`; 0 = inline).
std::vector<v1::RegisterRequest> RegisterMessages(const std::string& target_id,
                                                  const PointCloud& source,
                                                  const RegistrationOptions& options,
                                                  const Matrix4& initial,
                                                  const std::optional<Matrix4>& ground_truth = {},
                                                  std::size_t chunk_bytes = 0);

struct RegisterOutcome {
  grpc::Status status;
  std::vector<v1::RegisterResponse> responses;
  int progress_count() const;
  const v1::Accepted* accepted() const;  // null when absent
  const v1::Result* result() const;      // null when absent
  std::vector<const v1::Progress*> progress() const;
};

// A Register call running on its own thread, observable while it runs.
class RegisterCall {
 public:
  RegisterCall(const Client& client, std::vector<v1::RegisterRequest> messages,
               std::chrono::milliseconds timeout = std::chrono::seconds(60));
  ~RegisterCall();  // Cancel() + Join()

  // Blocks until `count` responses of this kind arrived (or the call ended / timed out).
  bool WaitForAccepted(std::chrono::milliseconds timeout = std::chrono::seconds(20));
  bool WaitForProgress(int count, std::chrono::milliseconds timeout = std::chrono::seconds(20));
  void Cancel() { context_.TryCancel(); }
  RegisterOutcome Join();

 private:
  void Run(std::vector<v1::RegisterRequest> messages);
  bool WaitFor(const std::function<bool()>& ready, std::chrono::milliseconds timeout);

  const Client& client_;
  grpc::ClientContext context_;
  std::mutex mutex_;
  std::condition_variable changed_;
  RegisterOutcome outcome_;
  bool finished_ = false;
  std::thread thread_;
};

// Runs a Register call to completion.
RegisterOutcome RunRegister(const Client& client, const std::vector<v1::RegisterRequest>& messages,
                            std::chrono::milliseconds timeout = std::chrono::seconds(60));

// Polls `condition` every 10 ms until it holds or `timeout` passes.
bool Eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout);

}  // namespace mlsreg::service_test
