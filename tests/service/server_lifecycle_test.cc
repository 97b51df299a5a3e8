// The server as a whole: health and graceful drain, reflection, request statistics, bearer
// tokens, TLS and mutual TLS.
#include <grpcpp/security/credentials.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "grpc/health/v1/health.grpc.pb.h"
#include "mlsreg/wire/convert.h"
#include "service_test_support.h"

namespace mlsreg::service_test {
namespace {

namespace fs = std::filesystem;
using grpc::health::v1::Health;
using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

// grpc.health.v1.Health/Check through its generated stub; -1 when the call itself fails.
int HealthStatus(const std::shared_ptr<grpc::Channel>& channel, const std::string& service) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  HealthCheckRequest request;
  request.set_service(service);
  HealthCheckResponse response;
  const grpc::Status status = Health::NewStub(channel)->Check(&context, request, &response);
  return status.ok() ? response.status() : -static_cast<int>(status.error_code()) - 100;
}

TEST(ServerLifecycleTest, HealthTurnsNotServingAndRunningWorkDrains) {
  ServerConfig config = TestConfig();
  config.workers = 2;
  config.drain_seconds = 4;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "bun045", Bun045()).ok());

  for (const char* service :
       {"", "mlsreg.v1.TargetService", "mlsreg.v1.RegistrationService", "mlsreg.v1.StatsService"}) {
    EXPECT_EQ(HealthStatus(client.channel, service), HealthCheckResponse::SERVING) << service;
  }
  EXPECT_EQ(HealthStatus(client.channel, "no.such.Service"),
            -static_cast<int>(grpc::StatusCode::NOT_FOUND) - 100);

  // One registration that ends by itself well within the drain time, one that never ends.
  RegistrationOptions finite = EndlessOptions();
  finite.num_samples = 500;  // 40 iterations: ~0.15 s (~1.5 s under ASan)
  finite.max_iterations = 40;
  RegisterCall finishing(client,
                         RegisterMessages("bun045", Bun000(), finite, PerturbedStart(5, 5, 20)));
  RegisterCall endless(
      client, RegisterMessages("bun045", Bun000(), EndlessOptions(), PerturbedStart(5, 5, 21)));
  ASSERT_TRUE(finishing.WaitForProgress(1));
  ASSERT_TRUE(endless.WaitForProgress(1));

  const auto shutdown_start = std::chrono::steady_clock::now();
  std::jthread shutdown([&] { server->Shutdown(); });  // joins even when a check fails
  EXPECT_TRUE(Eventually(
      [&] { return HealthStatus(client.channel, "") == HealthCheckResponse::NOT_SERVING; },
      std::chrono::seconds(1)));
  EXPECT_EQ(HealthStatus(client.channel, "mlsreg.v1.RegistrationService"),
            HealthCheckResponse::NOT_SERVING);
  // New work is refused while draining; other calls still answer.
  const RegisterOutcome refused = RunRegister(
      client, RegisterMessages("bun045", Bun000(), QuickOptions(), PerturbedStart(5, 5, 22)));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::UNAVAILABLE)
      << refused.status.error_message();
  EXPECT_FALSE(Stats(client).serving());

  const RegisterOutcome finished = finishing.Join();
  ASSERT_TRUE(finished.status.ok()) << finished.status.error_message();
  ASSERT_NE(finished.result(), nullptr);
  EXPECT_EQ(finished.result()->iterations(), 40);
  const RegisterOutcome stopped = endless.Join();
  EXPECT_EQ(stopped.status.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(stopped.status.error_message().find("shutting down"), std::string::npos)
      << stopped.status.error_message();
  shutdown.join();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - shutdown_start).count();
  EXPECT_GE(seconds, 3.9);  // waited the drain time for the endless one
  EXPECT_LT(seconds, 9.0);  // then stopped it promptly
  EXPECT_NE(HealthStatus(client.channel, ""), HealthCheckResponse::SERVING);
}

// grpc.reflection.v1alpha (what grpcurl and friends use), spoken with raw bytes: a
// ServerReflectionRequest{list_services: "*"} is field 7, length 1, "*". Returns the raw reply
// bytes, or the call's status when it failed.
absl::StatusOr<std::string> ListServicesByReflection(const Client& client) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
  std::unique_ptr<grpc::ClientReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>> stream(
      grpc::internal::ClientReaderWriterFactory<grpc::ByteBuffer, grpc::ByteBuffer>::Create(
          client.channel.get(),
          grpc::internal::RpcMethod(
              "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
              grpc::internal::RpcMethod::BIDI_STREAMING),
          &context));
  grpc::Slice slice(std::string("\x3a\x01*", 3));
  stream->Write(grpc::ByteBuffer(&slice, 1));
  stream->WritesDone();
  std::string bytes;
  grpc::ByteBuffer reply;
  while (stream->Read(&reply)) {
    std::vector<grpc::Slice> slices;
    if (!reply.Dump(&slices).ok()) break;
    for (const grpc::Slice& s : slices)
      bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  const grpc::Status status = stream->Finish();
  if (!status.ok()) return wire::ToAbslStatus(status);
  return bytes;
}

// gRPC turns SO_REUSEPORT on by default: a second server on the same port started too, and
// clients reached either one. Now the second one fails to start, saying why.
TEST(ServerLifecycleTest, ASecondServerOnABoundPortDoesNotStart) {
  auto first = StartServer(TestConfig());
  ASSERT_NE(first, nullptr);
  ServerConfig config = TestConfig();
  config.listen = "127.0.0.1:" + std::to_string(first->port());
  auto second = MlsregServer::Start(config);
  ASSERT_FALSE(second.ok()) << "a second server listens on " << config.listen;
  EXPECT_EQ(second.status().code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(second.status().message().find("cannot listen on '" + config.listen + "'"),
            std::string::npos)
      << second.status();
  EXPECT_NE(second.status().message().find("in use"), std::string::npos) << second.status();
  // The first one still serves.
  EXPECT_EQ(HealthStatus(Connect(first->port()).channel, ""), HealthCheckResponse::SERVING);
}

TEST(ServerLifecycleTest, ReflectionListsTheServicesWhenEnabled) {
  ServerConfig config = TestConfig();
  config.reflection = true;
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  auto bytes = ListServicesByReflection(client);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  for (const char* service : {"mlsreg.v1.TargetService", "mlsreg.v1.RegistrationService",
                              "mlsreg.v1.StatsService", "grpc.health.v1.Health"}) {
    EXPECT_NE(bytes->find(service), std::string::npos) << service;
  }
}

// Reflection answers without a token, so it is off unless asked for.
TEST(ServerLifecycleTest, ReflectionIsOffByDefault) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  EXPECT_EQ(ListServicesByReflection(client).status().code(), absl::StatusCode::kUnimplemented);
}

TEST(ServerLifecycleTest, StatsCountRequestsByCodeAndSummariseLatency) {
  auto server = StartServer(TestConfig());
  ASSERT_NE(server, nullptr);
  const Client client = Connect(server->port());
  ASSERT_TRUE(Upload(client, "small", Prefix(Bun000(), 1000)).ok());
  v1::Target target;
  EXPECT_TRUE(GetTarget(client, "small", &target).ok());
  EXPECT_EQ(GetTarget(client, "missing", &target).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(GetTarget(client, "missing", &target).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(GetTarget(client, "bad id", &target).error_code(), grpc::StatusCode::INVALID_ARGUMENT);

  const v1::GetStatsResponse stats = Stats(client);
  std::map<std::pair<std::string, std::string>, std::uint64_t> counts;
  for (const auto& c : stats.requests()) counts[{c.rpc(), c.code()}] = c.count();
  EXPECT_EQ((counts[{"CreateTarget", "OK"}]), 1u);
  EXPECT_EQ((counts[{"GetTarget", "OK"}]), 1u);
  EXPECT_EQ((counts[{"GetTarget", "NOT_FOUND"}]), 2u);
  EXPECT_EQ((counts[{"GetTarget", "INVALID_ARGUMENT"}]), 1u);
  bool found = false;
  for (const auto& l : stats.latencies()) {
    if (l.rpc() != "GetTarget") continue;
    found = true;
    EXPECT_EQ(l.count(), 4u);
    EXPECT_LE(l.p50_ms(), l.p90_ms());
    EXPECT_LE(l.p90_ms(), l.p99_ms());
    EXPECT_LE(l.p99_ms(), l.max_ms());
    EXPECT_GT(l.max_ms(), 0.0);
  }
  EXPECT_TRUE(found);
  EXPECT_EQ(stats.workers(), 2);
  EXPECT_EQ(stats.queue_capacity(), 8);  // 0 in the config: 4 x workers
  EXPECT_EQ(stats.cache_entries(), 1);
  EXPECT_EQ(stats.cache_bytes(), target.memory_bytes());
  EXPECT_EQ(stats.cache_budget_bytes(), TestConfig().cache_budget_bytes);
  EXPECT_GT(stats.uptime_seconds(), 0.0);
  EXPECT_TRUE(stats.serving());
}

TEST(ServerLifecycleTest, BearerTokensGuardEveryRpcAndDeleteNeedsTheAdminToken) {
  ServerConfig config = TestConfig();
  config.token = "user-secret";
  config.admin_token = "admin-secret";
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const Client anonymous = Connect(server->port());
  const Client wrong = Connect(anonymous.channel, "user-secreT");
  const Client user = Connect(anonymous.channel, "user-secret");
  const Client admin = Connect(anonymous.channel, "admin-secret");
  const PointCloud cloud = Prefix(Bun000(), 1000);

  for (const Client* c : {&anonymous, &wrong}) {
    grpc::ClientContext context;
    c->Prepare(&context);
    v1::GetStatsResponse stats;
    EXPECT_EQ(c->stats->GetStats(&context, {}, &stats).error_code(),
              grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_EQ(Upload(*c, "t", cloud).error_code(), grpc::StatusCode::UNAUTHENTICATED);
    const RegisterOutcome r =
        RunRegister(*c, RegisterMessages("t", cloud, QuickOptions(), Matrix4(Matrix4::Identity())));
    EXPECT_EQ(r.status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_EQ(r.accepted(), nullptr);
  }
  ASSERT_TRUE(Upload(user, "t", cloud).ok());
  v1::Target target;
  EXPECT_TRUE(GetTarget(user, "t", &target).ok());
  EXPECT_TRUE(GetTarget(admin, "t", &target).ok());  // the admin token is a user token too

  auto remove = [](const Client& c) {
    grpc::ClientContext context;
    c.Prepare(&context);
    v1::DeleteTargetRequest request;
    request.set_target_id("t");
    v1::DeleteTargetResponse response;
    return c.targets->DeleteTarget(&context, request, &response);
  };
  EXPECT_EQ(remove(user).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(remove(anonymous).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(remove(admin).ok());
  // Health stays open (load balancers and probes carry no token).
  EXPECT_EQ(HealthStatus(anonymous.channel, ""), HealthCheckResponse::SERVING);
}

// ---------------------------------------------------------------------------- TLS

// A throwaway CA with a server certificate (localhost, 127.0.0.1) and a client certificate.
class Certificates {
 public:
  static std::optional<Certificates> Make() {
    if (std::system("openssl version > /dev/null 2>&1") != 0) return std::nullopt;
    Certificates c;
    c.dir_ = fs::temp_directory_path() / ("mlsreg_tls_" + std::to_string(::getpid()));
    fs::remove_all(c.dir_);
    fs::create_directories(c.dir_);
    const std::string d = c.dir_.string();
    const std::string key = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
    std::ofstream(d + "/server.ext") << "subjectAltName=DNS:localhost,IP:127.0.0.1\n"
                                        "extendedKeyUsage=serverAuth\n";
    std::ofstream(d + "/client.ext") << "extendedKeyUsage=clientAuth\n";
    const std::string script =
        "cd " + d + " && openssl req -x509" + key +
        " -days 2 -subj /CN=mlsreg-test-ca -keyout ca.key -out ca.pem"
        " -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign"
        " && openssl req" +
        key +
        " -subj /CN=localhost -keyout server.key -out server.csr"
        " && openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2"
        " -extfile server.ext -out server.pem"
        " && openssl req" +
        key +
        " -subj /CN=mlsreg-test-client -keyout client.key -out client.csr"
        " && openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -days 2"
        " -extfile client.ext -out client.pem";
    if (std::system(("(" + script + ") > /dev/null 2>&1").c_str()) != 0) return std::nullopt;
    return c;
  }
  ~Certificates() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  Certificates(Certificates&& other) noexcept : dir_(std::exchange(other.dir_, {})) {}

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string read(const std::string& name) const {
    std::ifstream in(path(name));
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

 private:
  Certificates() = default;
  fs::path dir_;
};

std::shared_ptr<grpc::Channel> TlsChannel(const Certificates& certs, int port, bool client_cert) {
  grpc::SslCredentialsOptions options;
  options.pem_root_certs = certs.read("ca.pem");
  if (client_cert) {
    options.pem_private_key = certs.read("client.key");
    options.pem_cert_chain = certs.read("client.pem");
  }
  grpc::ChannelArguments args;
  args.SetSslTargetNameOverride("localhost");
  return grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port),
                                   grpc::SslCredentials(options), args);
}

grpc::Status StatsCall(const std::shared_ptr<grpc::Channel>& channel) {
  const Client client = Connect(channel);
  grpc::ClientContext context;
  client.Prepare(&context, std::chrono::seconds(5));
  v1::GetStatsResponse response;
  return client.stats->GetStats(&context, {}, &response);
}

TEST(ServerLifecycleTest, TlsServesTlsClientsOnly) {
  std::optional<Certificates> certs = Certificates::Make();
  if (!certs) GTEST_SKIP() << "openssl is not available";
  ServerConfig config = TestConfig();
  config.tls_cert = certs->path("server.pem");
  config.tls_key = certs->path("server.key");
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const grpc::Status tls = StatsCall(TlsChannel(*certs, server->port(), false));
  EXPECT_TRUE(tls.ok()) << tls.error_message();
  const grpc::Status plain = StatsCall(grpc::CreateChannel(
      "127.0.0.1:" + std::to_string(server->port()), grpc::InsecureChannelCredentials()));
  EXPECT_EQ(plain.error_code(), grpc::StatusCode::UNAVAILABLE) << plain.error_message();
  // A bunny travels over TLS as well.
  const Client client = Connect(TlsChannel(*certs, server->port(), false));
  EXPECT_TRUE(Upload(client, "bun", Prefix(Bun000(), 2000)).ok());
}

TEST(ServerLifecycleTest, MutualTlsRejectsClientsWithoutACertificate) {
  std::optional<Certificates> certs = Certificates::Make();
  if (!certs) GTEST_SKIP() << "openssl is not available";
  ServerConfig config = TestConfig();
  config.tls_cert = certs->path("server.pem");
  config.tls_key = certs->path("server.key");
  config.tls_client_ca = certs->path("ca.pem");
  auto server = StartServer(config);
  ASSERT_NE(server, nullptr);
  const grpc::Status with_cert = StatsCall(TlsChannel(*certs, server->port(), true));
  EXPECT_TRUE(with_cert.ok()) << with_cert.error_message();
  const grpc::Status without_cert = StatsCall(TlsChannel(*certs, server->port(), false));
  EXPECT_EQ(without_cert.error_code(), grpc::StatusCode::UNAVAILABLE)
      << without_cert.error_message();
}

}  // namespace
}  // namespace mlsreg::service_test
