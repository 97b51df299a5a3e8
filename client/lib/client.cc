#include "mlsreg/client/client.h"

#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "mlsreg/core/cloud_digest.h"
#include "mlsreg/io/io.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg::client {
namespace {

using SteadyClock = std::chrono::steady_clock;

// Metadata naming the target of a call, for proxies that route by it.
constexpr char kTargetHeader[] = "x-mlsreg-target";

// How long a replica that answered UNAVAILABLE is skipped when choosing where to send a call.
constexpr std::chrono::seconds kDownTime{2};

absl::StatusOr<std::string> ReadFile(const std::string& path, const char* what) {
  absl::StatusOr<std::string> bytes = ReadFileBytes(path);
  if (!bytes.ok()) {
    return absl::Status(bytes.status().code(),
                        absl::StrCat("cannot read ", what, ": ", bytes.status().message()));
  }
  return bytes;
}

// The server's retry hint for a failed call: nullopt when it gave none, a negative value for
// "never", else the delay it asked for.
std::optional<std::chrono::milliseconds> RetryAfter(const grpc::ClientContext& context) {
  const auto& trailers = context.GetServerTrailingMetadata();
  const auto it = trailers.find("mlsreg-retry-after-ms");
  if (it == trailers.end()) return std::nullopt;
  long ms = 0;
  const std::string value(it->second.data(), it->second.size());
  if (!absl::SimpleAtoi(value, &ms)) return std::nullopt;
  return std::chrono::milliseconds(ms);
}

// 64-bit FNV-1a followed by the splitmix64 finaliser: stable across platforms and runs.
std::uint64_t Hash64(std::string_view text) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
  h ^= h >> 30;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 27;
  h *= 0x94d049bb133111ebull;
  return h ^ (h >> 31);
}

// "dns:///name:port" -> every address behind the name, as "ip:port".
absl::StatusOr<std::vector<std::string>> ResolveDns(const std::string& target) {
  const std::string rest = target.substr(std::string("dns:///").size());
  const std::size_t colon = rest.rfind(':');
  if (colon == std::string::npos) {
    return absl::InvalidArgumentError("server address '" + target + "' lacks a port");
  }
  const std::string host = rest.substr(0, colon), port = rest.substr(colon + 1);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (int rc = getaddrinfo(host.c_str(), port.c_str(), &hints, &found); rc != 0) {
    return absl::UnavailableError(absl::StrCat("cannot resolve '", host, "': ", gai_strerror(rc)));
  }
  std::vector<std::string> addresses;
  for (addrinfo* a = found; a; a = a->ai_next) {
    char ip[NI_MAXHOST];
    if (getnameinfo(a->ai_addr, a->ai_addrlen, ip, sizeof ip, nullptr, 0, NI_NUMERICHOST) != 0) {
      continue;
    }
    const std::string address =
        a->ai_family == AF_INET6 ? absl::StrCat("[", ip, "]:", port) : absl::StrCat(ip, ":", port);
    if (std::find(addresses.begin(), addresses.end(), address) == addresses.end()) {
      addresses.push_back(address);
    }
  }
  freeaddrinfo(found);
  if (addresses.empty()) return absl::UnavailableError("'" + host + "' has no address");
  return addresses;
}

// Cancels a call's context when `*cancel` turns true, until destroyed: TryCancel is the only way
// to interrupt a blocking Read. Does nothing for a null flag.
class CancelWatcher {
 public:
  CancelWatcher(grpc::ClientContext& context, const std::atomic<bool>* cancel) {
    if (!cancel) return;
    thread_ = std::thread([this, &context, cancel] {
      while (!done_.load()) {
        if (cancel->load()) {
          context.TryCancel();
          return;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    });
  }
  ~CancelWatcher() {
    done_ = true;
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::atomic<bool> done_{false};
  std::thread thread_;
};

// The status of a finished streaming call. A CANCELLED this caller did not ask for means the
// server dropped the call (a replica that shuts down cancels calls it has not started): such a
// call changes nothing on the server, so it is UNAVAILABLE, retried on the next replica.
absl::Status StreamStatus(const grpc::Status& status, const std::atomic<bool>* cancel) {
  if (status.error_code() == grpc::StatusCode::CANCELLED && !(cancel && cancel->load())) {
    return absl::UnavailableError(
        absl::StrCat("the server cancelled the call: ", status.error_message()));
  }
  return wire::ToAbslStatus(status);
}

}  // namespace

// One server: its channel and stubs, and until when it is considered down.
struct Replica {
  std::string address;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::TargetService::Stub> targets;
  std::unique_ptr<v1::RegistrationService::Stub> registration;
  std::unique_ptr<v1::StatsService::Stub> stats;
  std::unique_ptr<grpc::health::v1::Health::Stub> health;
  std::atomic<SteadyClock::rep> down_until{0};

  bool down() const { return SteadyClock::now().time_since_epoch().count() < down_until.load(); }
  void MarkDown() { down_until = (SteadyClock::now() + kDownTime).time_since_epoch().count(); }
};

// The gRPC implementation of Client.
class GrpcClient final : public Client {
 public:
  struct Impl;
  GrpcClient(const ClientOptions& options, std::unique_ptr<Impl> impl);
  ~GrpcClient() override;

  using Client::UploadTarget;
  absl::StatusOr<TargetInfo> UploadTarget(const std::string& id,
                                          std::shared_ptr<const PointCloud> cloud) override;
  absl::StatusOr<TargetInfo> GetTarget(const std::string& id) override;
  std::string DigestAsSent(const PointCloud& cloud) const override;
  absl::StatusOr<std::vector<TargetInfo>> ListTargets() override;
  absl::Status DeleteTarget(const std::string& id) override;
  absl::StatusOr<RemoteRegistrationResult> Register(
      const std::string& target_id, const PointCloud& source, const Matrix4& initial,
      const RegistrationOptions& options, const std::optional<Matrix4>& ground_truth,
      const std::function<void(const IterationReport&)>& on_progress,
      const std::atomic<bool>* cancel) override;
  absl::StatusOr<RemoteAlignResult> AlignScans(
      const std::vector<RemoteScan>& scans, const AlignOptions& options,
      const std::function<void(const AlignEdge&, int done, int total)>& on_edge,
      const std::atomic<bool>* cancel) override;
  absl::StatusOr<ServerHealth> Health(std::size_t replica) override;
  absl::StatusOr<std::string> StatsJson(std::size_t replica) override;
  std::vector<std::string> replicas() const override;
  std::string ReplicaFor(const std::string& target_id) const override;

 private:
  std::unique_ptr<Impl> impl_;
};

struct GrpcClient::Impl {
  ClientOptions options;
  std::vector<std::unique_ptr<Replica>> replicas;
  std::mutex mutex;  // guards jitter and uploaded
  std::mt19937_64 jitter{std::random_device{}()};
  std::map<std::string, std::shared_ptr<const PointCloud>> uploaded;

  // Rendezvous (highest random weight) order of the replicas for a target id: adding or
  // removing a replica only moves the targets whose first choice it is.
  std::vector<Replica*> Order(const std::string& target_id) const {
    std::vector<std::pair<std::uint64_t, Replica*>> scored;
    for (const auto& r : replicas) {
      scored.emplace_back(Hash64(target_id + '\n' + r->address), r.get());
    }
    std::sort(scored.begin(), scored.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<Replica*> order;
    for (const auto& [score, r] : scored) order.push_back(r);
    return order;
  }

  // The first replica of the target's order that is not marked down (the first if all are).
  Replica& Choose(const std::string& target_id) const {
    const std::vector<Replica*> order = Order(target_id);
    for (Replica* r : order) {
      if (!r->down()) return *r;
    }
    return *order.front();
  }

  void PrepareContext(grpc::ClientContext& context) const {
    context.set_deadline(
        std::chrono::system_clock::now() +
        std::chrono::milliseconds(static_cast<long>(options.deadline_seconds * 1000.0)));
    if (!options.token.empty()) context.AddMetadata("authorization", "Bearer " + options.token);
  }

  // Sleeps a jittered backoff, and at least `at_least` (the server's hint).
  void Backoff(double& backoff, std::chrono::milliseconds at_least = {}) {
    double sleep_seconds;
    {
      std::lock_guard<std::mutex> lock(mutex);
      sleep_seconds = std::uniform_real_distribution<double>(0.0, backoff)(jitter);
    }
    sleep_seconds = std::max(sleep_seconds, static_cast<double>(at_least.count()) / 1e3);
    std::this_thread::sleep_for(std::chrono::duration<double>(sleep_seconds));
    backoff = std::min(backoff * 2.0, options.max_backoff_seconds);
  }

  // Runs `attempt(replica, context)` against `pick()` until it succeeds, fails permanently or
  // runs out of attempts. UNAVAILABLE marks the replica down (the next pick may differ);
  // UNAVAILABLE and RESOURCE_EXHAUSTED back off exponentially with full jitter, and at least as
  // long as the server's retry hint. A RESOURCE_EXHAUSTED the server calls final is not retried.
  // `on_not_found` (may be empty) may repair a NOT_FOUND once (e.g. by uploading the target)
  // and return true to retry at once.
  template <typename Result, typename Pick, typename Attempt>
  absl::StatusOr<Result> Call(const std::string& target_id, Pick pick, Attempt attempt,
                              int* attempts_out = nullptr,
                              const std::function<bool(Replica&)>& on_not_found = {}) {
    double backoff = options.initial_backoff_seconds;
    bool repaired = false;
    absl::StatusOr<Result> result = absl::UnknownError("no attempt made");
    const int max_attempts = std::max(1, options.max_attempts);
    for (int n = 1; n <= max_attempts; ++n) {
      Replica& replica = pick();
      grpc::ClientContext context;
      PrepareContext(context);
      // Lets an L7 proxy (Envoy ring hash) route by target too; see docs/operations.md.
      if (!target_id.empty()) context.AddMetadata(kTargetHeader, target_id);
      result = attempt(replica, context);
      if (attempts_out) *attempts_out = n;
      if (result.ok()) return result;
      const absl::StatusCode code = result.status().code();
      if (code == absl::StatusCode::kNotFound && on_not_found && !repaired) {
        repaired = true;
        if (on_not_found(replica)) continue;
        return result;
      }
      if (code != absl::StatusCode::kUnavailable && code != absl::StatusCode::kResourceExhausted) {
        return result;
      }
      const std::optional<std::chrono::milliseconds> hint = RetryAfter(context);
      if (hint && hint->count() < 0) return result;  // the server says it can never succeed
      if (n == max_attempts) break;
      if (code == absl::StatusCode::kUnavailable) {
        replica.MarkDown();
        // Another replica can take the call at once; back off only when none is left.
        if (&pick() != &replica) continue;
      }
      Backoff(backoff, hint.value_or(std::chrono::milliseconds(0)));
    }
    return result;
  }

  absl::StatusOr<TargetInfo> UploadTo(Replica& replica, grpc::ClientContext& context,
                                      const std::string& id, const PointCloud& cloud);
  // What the server will compute for the cloud as encoded.
  static std::string DigestOfEncoded(const v1::CloudHeader& header, const std::string& payload,
                                     const PointCloud& cloud);
};

GrpcClient::GrpcClient(const ClientOptions& options, std::unique_ptr<Impl> impl)
    : Client(options), impl_(std::move(impl)) {}
GrpcClient::~GrpcClient() = default;

absl::StatusOr<std::unique_ptr<Client>> Client::Connect(const ClientOptions& options) {
  if (options.address.empty()) return absl::InvalidArgumentError("server address is empty");
  if (options.chunk_bytes == 0 || options.chunk_bytes > (4u << 20)) {
    return absl::InvalidArgumentError("chunk_bytes must be in [1, 4 MiB]");
  }
  std::vector<std::string> addresses;
  if (options.address.rfind("dns:///", 0) == 0) {
    auto resolved = ResolveDns(options.address);
    if (!resolved.ok()) return resolved.status();
    addresses = *resolved;
  } else {
    for (absl::string_view a : absl::StrSplit(options.address, ',', absl::SkipWhitespace())) {
      addresses.emplace_back(a);
    }
  }
  if (addresses.empty()) return absl::InvalidArgumentError("no server address given");

  std::shared_ptr<grpc::ChannelCredentials> credentials;
  if (options.tls) {
    grpc::SslCredentialsOptions ssl;
    if (!options.ca_cert.empty()) {
      auto ca = ReadFile(options.ca_cert, "CA certificate");
      if (!ca.ok()) return ca.status();
      ssl.pem_root_certs = *ca;
    }
    if (!options.client_cert.empty() || !options.client_key.empty()) {
      auto cert = ReadFile(options.client_cert, "client certificate");
      if (!cert.ok()) return cert.status();
      auto key = ReadFile(options.client_key, "client key");
      if (!key.ok()) return key.status();
      ssl.pem_cert_chain = *cert;
      ssl.pem_private_key = *key;
    }
    credentials = grpc::SslCredentials(ssl);
  } else {
    credentials = grpc::InsecureChannelCredentials();
  }
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetMaxSendMessageSize(64 << 20);
  auto impl = std::make_unique<GrpcClient::Impl>();
  impl->options = options;
  for (const std::string& address : addresses) {
    auto r = std::make_unique<Replica>();
    r->address = address;
    r->channel = grpc::CreateCustomChannel(address, credentials, args);
    r->targets = v1::TargetService::NewStub(r->channel);
    r->registration = v1::RegistrationService::NewStub(r->channel);
    r->stats = v1::StatsService::NewStub(r->channel);
    r->health = grpc::health::v1::Health::NewStub(r->channel);
    impl->replicas.push_back(std::move(r));
  }
  return std::unique_ptr<Client>(new GrpcClient(options, std::move(impl)));
}

std::vector<std::string> GrpcClient::replicas() const {
  std::vector<std::string> out;
  for (const auto& r : impl_->replicas) out.push_back(r->address);
  return out;
}

std::string GrpcClient::ReplicaFor(const std::string& target_id) const {
  return impl_->Order(target_id).front()->address;
}

absl::StatusOr<TargetInfo> GrpcClient::Impl::UploadTo(Replica& replica,
                                                      grpc::ClientContext& context,
                                                      const std::string& id,
                                                      const PointCloud& cloud) {
  v1::CreateTargetRequest header_message;
  header_message.mutable_header()->set_target_id(id);
  std::string payload;
  wire::EncodeCloud(cloud, options.float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64,
                    header_message.mutable_header()->mutable_cloud(), &payload);
  header_message.mutable_header()->set_content_digest(
      DigestOfEncoded(header_message.header().cloud(), payload, cloud));
  v1::Target response;
  auto writer = replica.targets->CreateTarget(&context, &response);
  // A server that already holds this content (or refuses the header) finishes the call early:
  // the writes then fail and Finish tells why, or returns the stored target.
  if (writer->Write(header_message)) {
    v1::CreateTargetRequest chunk_message;
    wire::WriteChunks(payload, options.chunk_bytes, [&](const v1::CloudChunk& chunk) {
      *chunk_message.mutable_chunk() = chunk;
      return writer->Write(chunk_message);
    });
  }
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  if (!status.ok()) return wire::ToAbslStatus(status);
  return wire::FromProto(response);
}

std::string GrpcClient::Impl::DigestOfEncoded(const v1::CloudHeader& header,
                                              const std::string& payload, const PointCloud& cloud) {
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT64) return CloudDigest(cloud);  // exact
  auto decoded = wire::DecodeCloud(header, payload, "cloud");
  return decoded.ok() ? CloudDigest(*decoded) : std::string();  // the server will refuse it
}

std::string GrpcClient::DigestAsSent(const PointCloud& cloud) const {
  v1::CloudHeader header;
  std::string payload;
  wire::EncodeCloud(cloud,
                    Client::options().float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64,
                    &header, &payload);
  return Impl::DigestOfEncoded(header, payload, cloud);
}

absl::StatusOr<TargetInfo> GrpcClient::UploadTarget(const std::string& id,
                                                    std::shared_ptr<const PointCloud> cloud) {
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->uploaded[id] = cloud;
  }
  return impl_->Call<TargetInfo>(
      id, [&]() -> Replica& { return impl_->Choose(id); },
      [&](Replica& replica, grpc::ClientContext& context) {
        return impl_->UploadTo(replica, context, id, *cloud);
      });
}

absl::StatusOr<TargetInfo> GrpcClient::GetTarget(const std::string& id) {
  v1::GetTargetRequest request;
  request.set_target_id(id);
  return impl_->Call<TargetInfo>(
      id, [&]() -> Replica& { return impl_->Choose(id); },
      [&](Replica& replica, grpc::ClientContext& context) -> absl::StatusOr<TargetInfo> {
        v1::Target response;
        const grpc::Status status = replica.targets->GetTarget(&context, request, &response);
        if (!status.ok()) return wire::ToAbslStatus(status);
        return wire::FromProto(response);
      });
}

absl::StatusOr<std::vector<TargetInfo>> GrpcClient::ListTargets() {
  std::vector<TargetInfo> all;
  for (const auto& replica : impl_->replicas) {
    std::string token;
    do {
      v1::ListTargetsRequest request;
      request.set_page_size(1000);
      request.set_page_token(token);
      auto page = impl_->Call<v1::ListTargetsResponse>(
          "", [&]() -> Replica& { return *replica; },
          [&](Replica& r, grpc::ClientContext& context) -> absl::StatusOr<v1::ListTargetsResponse> {
            v1::ListTargetsResponse response;
            const grpc::Status status = r.targets->ListTargets(&context, request, &response);
            if (!status.ok()) return wire::ToAbslStatus(status);
            return response;
          });
      if (!page.ok()) {
        return absl::Status(page.status().code(),
                            absl::StrCat(replica->address, ": ", page.status().message()));
      }
      for (const v1::Target& t : page->targets()) all.push_back(wire::FromProto(t));
      token = page->next_page_token();
    } while (!token.empty());
  }
  std::sort(all.begin(), all.end(),
            [](const TargetInfo& a, const TargetInfo& b) { return a.id < b.id; });
  return all;
}

absl::Status GrpcClient::DeleteTarget(const std::string& id) {
  v1::DeleteTargetRequest request;
  request.set_target_id(id);
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->uploaded.erase(id);
  }
  return impl_
      ->Call<bool>(
          id, [&]() -> Replica& { return impl_->Choose(id); },
          [&](Replica& replica, grpc::ClientContext& context) -> absl::StatusOr<bool> {
            v1::DeleteTargetResponse response;
            const grpc::Status status = replica.targets->DeleteTarget(&context, request, &response);
            if (!status.ok()) return wire::ToAbslStatus(status);
            return true;
          })
      .status();
}

absl::StatusOr<RemoteRegistrationResult> GrpcClient::Register(
    const std::string& target_id, const PointCloud& source, const Matrix4& initial,
    const RegistrationOptions& options, const std::optional<Matrix4>& ground_truth,
    const std::function<void(const IterationReport&)>& on_progress,
    const std::atomic<bool>* cancel) {
  v1::RegisterRequest header_message;
  v1::RegisterHeader* header = header_message.mutable_header();
  std::string payload;
  wire::BuildRegisterHeader(
      target_id, source,
      Client::options().float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64, options,
      initial, ground_truth, header, &payload);
  const bool inline_source = payload.size() <= Client::options().chunk_bytes;
  if (inline_source) header->set_source_data(payload);

  // NOT_FOUND on a target this client uploaded: the replica lost it (restart without storage)
  // or the target was re-routed here; upload it again and retry once.
  auto reupload = [&](Replica& replica) {
    std::shared_ptr<const PointCloud> cloud;
    {
      std::lock_guard<std::mutex> lock(impl_->mutex);
      auto it = impl_->uploaded.find(target_id);
      if (it == impl_->uploaded.end()) return false;
      cloud = it->second;
    }
    grpc::ClientContext context;
    impl_->PrepareContext(context);
    context.AddMetadata(kTargetHeader, target_id);
    auto uploaded = impl_->UploadTo(replica, context, target_id, *cloud);
    return uploaded.ok() || uploaded.status().code() == absl::StatusCode::kAlreadyExists;
  };

  int attempts = 1;
  auto result = impl_->Call<RemoteRegistrationResult>(
      target_id, [&]() -> Replica& { return impl_->Choose(target_id); },
      [&](Replica& replica,
          grpc::ClientContext& context) -> absl::StatusOr<RemoteRegistrationResult> {
        RemoteRegistrationResult out;
        auto stream = replica.registration->Register(&context);
        const CancelWatcher watcher(context, cancel);
        if (stream->Write(header_message) && !inline_source) {
          v1::RegisterRequest chunk_message;
          wire::WriteChunks(payload, Client::options().chunk_bytes,
                            [&](const v1::CloudChunk& chunk) {
                              *chunk_message.mutable_source_chunk() = chunk;
                              return stream->Write(chunk_message);
                            });
        }
        stream->WritesDone();
        v1::RegisterResponse response;
        bool have_result = false;
        while (stream->Read(&response)) {
          if (response.has_accepted()) {
            out.request_id = response.accepted().request_id();
          } else if (response.has_progress()) {
            const IterationReport report = wire::FromProto(response.progress());
            out.result.trace.push_back(report);
            if (on_progress) on_progress(report);
          } else if (response.has_result()) {
            std::vector<IterationReport> trace = std::move(out.result.trace);
            out.result = wire::FromProto(response.result());
            out.result.trace = std::move(trace);
            out.queue_seconds = response.result().timings().queue_seconds();
            if (response.result().has_ground_truth_error()) {
              out.ground_truth_error = wire::FromProto(response.result().ground_truth_error());
            }
            have_result = true;
          }
        }
        if (absl::Status status = StreamStatus(stream->Finish(), cancel); !status.ok()) {
          return status;
        }
        if (!have_result)
          return absl::DataLossError("the server ended the stream without a result");
        return out;
      },
      &attempts, reupload);
  if (result.ok()) result->attempts = attempts;
  return result;
}

absl::StatusOr<RemoteAlignResult> GrpcClient::AlignScans(
    const std::vector<RemoteScan>& scans, const AlignOptions& options,
    const std::function<void(const AlignEdge&, int, int)>& on_edge,
    const std::atomic<bool>* cancel) {
  v1::AlignScansRequest header_message;
  v1::AlignScansHeader* header = header_message.mutable_header();
  wire::AlignOptionsToProto(options, header);
  std::string payload, route;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    v1::AlignScan* scan = header->add_scans();
    if (!scans[i].target_id.empty()) {
      scan->set_target_id(scans[i].target_id);
      if (route.empty()) route = scans[i].target_id;
    } else if (scans[i].cloud) {
      std::string data;
      wire::EncodeCloud(
          *scans[i].cloud,
          Client::options().float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64,
          scan->mutable_cloud(), &data);
      payload += data;
    } else {
      return absl::InvalidArgumentError(
          absl::StrCat("scans[", i, "]: give a target id or a cloud"));
    }
  }
  int attempts = 1;
  // A retried call runs every edge again: each is reported once, the first time it arrives.
  std::set<std::pair<int, int>> reported;
  auto result = impl_->Call<RemoteAlignResult>(
      route, [&]() -> Replica& { return impl_->Choose(route); },
      [&](Replica& replica, grpc::ClientContext& context) -> absl::StatusOr<RemoteAlignResult> {
        RemoteAlignResult out;
        auto stream = replica.registration->AlignScans(&context);
        const CancelWatcher watcher(context, cancel);
        if (stream->Write(header_message) && !payload.empty()) {
          v1::AlignScansRequest chunk_message;
          wire::WriteChunks(payload, Client::options().chunk_bytes,
                            [&](const v1::CloudChunk& chunk) {
                              *chunk_message.mutable_scan_chunk() = chunk;
                              return stream->Write(chunk_message);
                            });
        }
        stream->WritesDone();
        v1::AlignScansResponse response;
        bool have_result = false;
        while (stream->Read(&response)) {
          if (response.has_accepted()) {
            out.request_id = response.accepted().request_id();
          } else if (response.has_progress()) {
            const v1::AlignEdge& edge = response.progress().edge();
            if (on_edge && reported.emplace(edge.from(), edge.to()).second) {
              on_edge(wire::FromProto(edge), static_cast<int>(reported.size()),
                      response.progress().edges_total());
            }
          } else if (response.has_result()) {
            out.result = wire::FromProto(response.result());
            out.queue_seconds = response.result().queue_seconds();
            have_result = true;
          }
        }
        if (absl::Status status = StreamStatus(stream->Finish(), cancel); !status.ok()) {
          return status;
        }
        if (!have_result)
          return absl::DataLossError("the server ended the stream without a result");
        return out;
      },
      &attempts);
  if (result.ok()) result->attempts = attempts;
  return result;
}

absl::StatusOr<ServerHealth> GrpcClient::Health(std::size_t replica_index) {
  if (replica_index >= impl_->replicas.size()) {
    return absl::InvalidArgumentError("no such replica");
  }
  Replica& replica = *impl_->replicas[replica_index];
  return impl_->Call<ServerHealth>(
      "", [&]() -> Replica& { return replica; },
      [&](Replica& r, grpc::ClientContext& context) -> absl::StatusOr<ServerHealth> {
        grpc::health::v1::HealthCheckRequest request;
        grpc::health::v1::HealthCheckResponse response;
        const grpc::Status status = r.health->Check(&context, request, &response);
        if (!status.ok()) return wire::ToAbslStatus(status);
        ServerHealth health;
        health.serving = response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
        health.status =
            grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status());
        return health;
      });
}

absl::StatusOr<std::string> GrpcClient::StatsJson(std::size_t replica_index) {
  if (replica_index >= impl_->replicas.size()) {
    return absl::InvalidArgumentError("no such replica");
  }
  Replica& replica = *impl_->replicas[replica_index];
  auto stats = impl_->Call<v1::GetStatsResponse>(
      "", [&]() -> Replica& { return replica; },
      [&](Replica& r, grpc::ClientContext& context) -> absl::StatusOr<v1::GetStatsResponse> {
        v1::GetStatsResponse response;
        const grpc::Status status = r.stats->GetStats(&context, v1::GetStatsRequest(), &response);
        if (!status.ok()) return wire::ToAbslStatus(status);
        return response;
      });
  if (!stats.ok()) return stats.status();
  std::string json;
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = true;
  print.always_print_primitive_fields = true;
  if (!google::protobuf::util::MessageToJsonString(*stats, &json, print).ok()) {
    return absl::InternalError("cannot render statistics as JSON");
  }
  return json;
}

}  // namespace mlsreg::client
