#include "mlsreg/client/client.h"

#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>

#include <chrono>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg::client {
namespace {

absl::StatusOr<std::string> ReadFile(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot read ", what, " '", path, "'"));
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

bool IsTransient(absl::StatusCode code) {
  return code == absl::StatusCode::kUnavailable || code == absl::StatusCode::kResourceExhausted;
}

TargetInfo FromProto(const v1::Target& t) {
  TargetInfo info;
  info.id = t.target_id();
  info.state = t.state() == v1::TARGET_STATE_READY    ? "ready"
               : t.state() == v1::TARGET_STATE_STORED ? "stored"
                                                      : "unknown";
  info.points = t.point_count();
  info.memory_bytes = t.memory_bytes();
  info.sampling_distance = t.sampling_distance();
  info.build_seconds = t.build_seconds();
  info.registrations = t.registrations();
  return info;
}

}  // namespace

struct Client::Impl {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::TargetService::Stub> targets;
  std::unique_ptr<v1::RegistrationService::Stub> registration;
  std::unique_ptr<v1::StatsService::Stub> stats;
  std::unique_ptr<grpc::health::v1::Health::Stub> health;
  std::mt19937_64 jitter{std::random_device{}()};
  std::mutex jitter_mutex;
};

Client::Client(const ClientOptions& options, std::unique_ptr<Impl> impl)
    : options_(options), impl_(std::move(impl)) {}
Client::~Client() = default;

absl::StatusOr<std::unique_ptr<Client>> Client::Connect(const ClientOptions& options) {
  if (options.address.empty()) return absl::InvalidArgumentError("server address is empty");
  if (options.chunk_bytes == 0 || options.chunk_bytes > (4u << 20)) {
    return absl::InvalidArgumentError("chunk_bytes must be in [1, 4 MiB]");
  }
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
  auto impl = std::make_unique<Impl>();
  impl->channel = grpc::CreateCustomChannel(options.address, credentials, args);
  impl->targets = v1::TargetService::NewStub(impl->channel);
  impl->registration = v1::RegistrationService::NewStub(impl->channel);
  impl->stats = v1::StatsService::NewStub(impl->channel);
  impl->health = grpc::health::v1::Health::NewStub(impl->channel);
  return std::unique_ptr<Client>(new Client(options, std::move(impl)));
}

namespace {

// Runs `attempt(context)` until it succeeds, fails permanently, or runs out of attempts;
// transient failures back off exponentially with full jitter.
template <typename Result, typename Attempt>
absl::StatusOr<Result> WithRetries(const ClientOptions& options, std::mt19937_64& rng,
                                   std::mutex& rng_mutex, Attempt attempt,
                                   int* attempts_out = nullptr) {
  double backoff = options.initial_backoff_seconds;
  absl::StatusOr<Result> result = absl::UnknownError("no attempt made");
  for (int attempt_number = 1; attempt_number <= std::max(1, options.max_attempts);
       ++attempt_number) {
    grpc::ClientContext context;
    context.set_deadline(
        std::chrono::system_clock::now() +
        std::chrono::milliseconds(static_cast<long>(options.deadline_seconds * 1000.0)));
    if (!options.token.empty()) context.AddMetadata("authorization", "Bearer " + options.token);
    result = attempt(context);
    if (attempts_out) *attempts_out = attempt_number;
    if (result.ok() || !IsTransient(result.status().code())) return result;
    if (attempt_number == options.max_attempts) break;
    double sleep_seconds;
    {
      std::lock_guard<std::mutex> lock(rng_mutex);
      sleep_seconds = std::uniform_real_distribution<double>(0.0, backoff)(rng);
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(sleep_seconds));
    backoff = std::min(backoff * 2.0, options.max_backoff_seconds);
  }
  return result;
}

}  // namespace

absl::StatusOr<TargetInfo> Client::UploadTarget(const std::string& id, const PointCloud& cloud) {
  v1::CreateTargetRequest header_message;
  header_message.mutable_header()->set_target_id(id);
  std::string payload;
  wire::EncodeCloud(cloud, options_.float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64,
                    header_message.mutable_header()->mutable_cloud(), &payload);
  return WithRetries<TargetInfo>(options_, impl_->jitter, impl_->jitter_mutex,
                                 [&](grpc::ClientContext& context) -> absl::StatusOr<TargetInfo> {
                                   v1::Target response;
                                   auto writer = impl_->targets->CreateTarget(&context, &response);
                                   bool open = writer->Write(header_message);
                                   v1::CreateTargetRequest chunk_message;
                                   for (std::size_t offset = 0; open && offset < payload.size();
                                        offset += options_.chunk_bytes) {
                                     v1::CloudChunk* chunk = chunk_message.mutable_chunk();
                                     chunk->set_offset(offset);
                                     chunk->set_data(payload.substr(offset, options_.chunk_bytes));
                                     open = writer->Write(chunk_message);
                                   }
                                   writer->WritesDone();
                                   const grpc::Status status = writer->Finish();
                                   if (!status.ok()) return wire::ToAbslStatus(status);
                                   return FromProto(response);
                                 });
}

absl::StatusOr<TargetInfo> Client::GetTarget(const std::string& id) {
  v1::GetTargetRequest request;
  request.set_target_id(id);
  return WithRetries<TargetInfo>(options_, impl_->jitter, impl_->jitter_mutex,
                                 [&](grpc::ClientContext& context) -> absl::StatusOr<TargetInfo> {
                                   v1::Target response;
                                   const grpc::Status status =
                                       impl_->targets->GetTarget(&context, request, &response);
                                   if (!status.ok()) return wire::ToAbslStatus(status);
                                   return FromProto(response);
                                 });
}

absl::StatusOr<std::vector<TargetInfo>> Client::ListTargets() {
  std::vector<TargetInfo> all;
  std::string token;
  do {
    v1::ListTargetsRequest request;
    request.set_page_size(1000);
    request.set_page_token(token);
    auto page = WithRetries<v1::ListTargetsResponse>(
        options_, impl_->jitter, impl_->jitter_mutex,
        [&](grpc::ClientContext& context) -> absl::StatusOr<v1::ListTargetsResponse> {
          v1::ListTargetsResponse response;
          const grpc::Status status = impl_->targets->ListTargets(&context, request, &response);
          if (!status.ok()) return wire::ToAbslStatus(status);
          return response;
        });
    if (!page.ok()) return page.status();
    for (const v1::Target& t : page->targets()) all.push_back(FromProto(t));
    token = page->next_page_token();
  } while (!token.empty());
  return all;
}

absl::Status Client::DeleteTarget(const std::string& id) {
  v1::DeleteTargetRequest request;
  request.set_target_id(id);
  return WithRetries<bool>(options_, impl_->jitter, impl_->jitter_mutex,
                           [&](grpc::ClientContext& context) -> absl::StatusOr<bool> {
                             v1::DeleteTargetResponse response;
                             const grpc::Status status =
                                 impl_->targets->DeleteTarget(&context, request, &response);
                             if (!status.ok()) return wire::ToAbslStatus(status);
                             return true;
                           })
      .status();
}

absl::StatusOr<RemoteRegistrationResult> Client::Register(
    const std::string& target_id, const PointCloud& source, const Matrix4& initial,
    const RegistrationOptions& options, const std::optional<Matrix4>& ground_truth,
    const std::function<void(const IterationReport&)>& on_progress,
    const std::atomic<bool>* cancel) {
  v1::RegisterRequest header_message;
  v1::RegisterHeader* header = header_message.mutable_header();
  header->set_target_id(target_id);
  v1::Method method;
  wire::OptionsToProto(options, &method, header->mutable_parameters());
  header->set_method(method);
  wire::ToProto(initial, header->mutable_initial_transform());
  if (ground_truth) wire::ToProto(*ground_truth, header->mutable_ground_truth());
  std::string payload;
  wire::EncodeCloud(source, options_.float32 ? v1::SCALAR_TYPE_FLOAT32 : v1::SCALAR_TYPE_FLOAT64,
                    header->mutable_source(), &payload);
  const bool inline_source = payload.size() <= options_.chunk_bytes;
  if (inline_source) header->set_source_data(payload);

  int attempts = 1;
  auto result = WithRetries<RemoteRegistrationResult>(
      options_, impl_->jitter, impl_->jitter_mutex,
      [&](grpc::ClientContext& context) -> absl::StatusOr<RemoteRegistrationResult> {
        RemoteRegistrationResult out;
        auto stream = impl_->registration->Register(&context);
        // Cancellation watcher: TryCancel is the only way to interrupt a blocking Read.
        std::atomic<bool> done{false};
        std::thread watcher;
        if (cancel) {
          watcher = std::thread([&] {
            while (!done.load()) {
              if (cancel->load()) {
                context.TryCancel();
                return;
              }
              std::this_thread::sleep_for(std::chrono::milliseconds(20));
            }
          });
        }
        bool open = stream->Write(header_message);
        if (!inline_source) {
          v1::RegisterRequest chunk_message;
          for (std::size_t offset = 0; open && offset < payload.size();
               offset += options_.chunk_bytes) {
            v1::CloudChunk* chunk = chunk_message.mutable_source_chunk();
            chunk->set_offset(offset);
            chunk->set_data(payload.substr(offset, options_.chunk_bytes));
            open = stream->Write(chunk_message);
          }
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
              const v1::GroundTruthError& e = response.result().ground_truth_error();
              out.ground_truth_error = PoseError{e.rmse_d(), e.success(), e.rotation_error_deg(),
                                                 e.translation_error_d()};
            }
            have_result = true;
          }
        }
        const grpc::Status status = stream->Finish();
        done = true;
        if (watcher.joinable()) watcher.join();
        if (!status.ok()) return wire::ToAbslStatus(status);
        if (!have_result)
          return absl::DataLossError("the server ended the stream without a result");
        return out;
      },
      &attempts);
  if (result.ok()) result->attempts = attempts;
  return result;
}

absl::StatusOr<ServerHealth> Client::Health() {
  return WithRetries<ServerHealth>(
      options_, impl_->jitter, impl_->jitter_mutex,
      [&](grpc::ClientContext& context) -> absl::StatusOr<ServerHealth> {
        grpc::health::v1::HealthCheckRequest request;
        grpc::health::v1::HealthCheckResponse response;
        const grpc::Status status = impl_->health->Check(&context, request, &response);
        if (!status.ok()) return wire::ToAbslStatus(status);
        ServerHealth health;
        health.serving = response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
        health.status =
            grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status());
        return health;
      });
}

absl::StatusOr<std::string> Client::StatsJson() {
  auto stats = WithRetries<v1::GetStatsResponse>(
      options_, impl_->jitter, impl_->jitter_mutex,
      [&](grpc::ClientContext& context) -> absl::StatusOr<v1::GetStatsResponse> {
        v1::GetStatsResponse response;
        const grpc::Status status =
            impl_->stats->GetStats(&context, v1::GetStatsRequest(), &response);
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
