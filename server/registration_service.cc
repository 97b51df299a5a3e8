// RegistrationService.Register: validates the whole request up front, admits it to the job
// pool, then relays the worker's progress (latest wins) and the result to the client.
#include <chrono>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "grpcpp/grpcpp.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"
#include "server/chunked_payload.h"
#include "server/ids.h"
#include "server/registration_job.h"
#include "server/rpc_scope.h"
#include "server/services.h"

namespace mlsreg::server {
namespace {

using RegisterStream = grpc::ServerReaderWriter<v1::RegisterResponse, v1::RegisterRequest>;

// How often the handler looks at its call while the worker is silent (cancellation latency).
constexpr std::chrono::milliseconds kPollInterval{50};

// A registration needs at least this many source points (the library's own minimum).
constexpr std::uint64_t kMinSourcePoints = 3;

class RegisterHandler {
 public:
  RegisterHandler(ServiceContext& c, grpc::ServerContext* ctx, RegisterStream* stream,
                  RpcScope* scope)
      : c_(c), ctx_(ctx), stream_(stream), scope_(scope) {}

  absl::Status Run() {
    if (absl::Status s = c_.auth.Check(*ctx_, Access::kUser); !s.ok()) return s;
    if (!c_.state.accepting()) return absl::UnavailableError("server is shutting down");
    auto input = ReadRequest();
    if (!input.ok()) return input.status();
    const std::string request_id = input->request_id;
    auto job =
        std::make_shared<RegistrationJob>(*std::move(input), &c_.cache, &c_.state.stop_flag());
    auto position = c_.jobs.TrySubmit([job] { job->Run(); });
    if (!position.ok()) return position.status();

    v1::RegisterResponse accepted;
    accepted.mutable_accepted()->set_request_id(request_id);
    accepted.mutable_accepted()->set_queue_position(*position);
    if (!stream_->Write(accepted)) return ClientGone(*job);
    return RelayUntilDone(*job);
  }

 private:
  // Everything is checked before the job is admitted, so a bad request never takes a worker.
  absl::StatusOr<RegistrationInput> ReadRequest() {
    v1::RegisterRequest first;
    if (!stream_->Read(&first)) {
      return absl::InvalidArgumentError("header: the stream ended before the header");
    }
    if (!first.has_header()) {
      return absl::InvalidArgumentError("header: the first message must be the header");
    }
    v1::RegisterHeader& header = *first.mutable_header();
    RegistrationInput in;
    if (absl::Status s = ParseHeader(header, &in); !s.ok()) return s;
    auto expected = CheckSourceHeader(header.source());
    if (!expected.ok()) return expected.status();
    // An unknown target is reported before the source is transferred. A resident target is
    // pinned from here on, so it cannot be evicted while this request waits in the queue.
    auto target = c_.cache.Peek(in.target_id);
    if (!target.ok()) return target.status();
    in.target = *std::move(target);
    auto source = ReadSource(header, *expected);
    if (!source.ok()) return source.status();
    in.source = *std::move(source);
    in.deadline = ctx_->deadline();
    scope_->add_detail(absl::StrCat("method=", std::string(wire::MethodName(header.method())),
                                    " source_points=", in.source.size()));
    return in;
  }

  // Ids, method, parameters and transforms.
  absl::Status ParseHeader(const v1::RegisterHeader& header, RegistrationInput* in) {
    in->request_id = header.request_id().empty() ? NewRequestId() : header.request_id();
    if (absl::Status s = ValidateRequestId(in->request_id, "header.request_id"); !s.ok()) return s;
    scope_->set_request_id(in->request_id);
    if (absl::Status s = ValidateTargetId(header.target_id(), "header.target_id"); !s.ok()) {
      return s;
    }
    in->target_id = header.target_id();
    scope_->set_target_id(in->target_id);
    auto options = wire::OptionsFromProto(header.method(), header.parameters());
    if (!options.ok()) return options.status();
    in->options = *options;
    if (header.has_initial_transform()) {
      auto m = wire::FromProto(header.initial_transform(), "header.initial_transform");
      if (!m.ok()) return m.status();
      in->initial = *m;
    }
    if (header.has_ground_truth()) {
      auto m = wire::FromProto(header.ground_truth(), "header.ground_truth");
      if (!m.ok()) return m.status();
      in->ground_truth = *m;
    }
    return absl::OkStatus();
  }

  // The payload size the source header declares.
  absl::StatusOr<std::uint64_t> CheckSourceHeader(const v1::CloudHeader& source) {
    auto expected = wire::CheckCloudHeader(source, c_.config.max_points, "header.source");
    if (!expected.ok()) return expected.status();
    if (source.point_count() < kMinSourcePoints) {
      return absl::InvalidArgumentError(
          absl::StrCat("header.source.point_count: a registration needs at least ",
                       kMinSourcePoints, " points (got ", source.point_count(), ")"));
    }
    return expected;
  }

  // The source from the inline payload, or from the chunks that follow the header.
  absl::StatusOr<PointCloud> ReadSource(v1::RegisterHeader& header, std::uint64_t expected) {
    std::string payload;
    if (!header.source_data().empty()) {
      if (header.source_data().size() != expected) {
        return absl::InvalidArgumentError(
            absl::StrCat("header.source_data: ", header.source_data().size(), " bytes, but ",
                         header.source().point_count(), " points of ",
                         wire::RecordBytes(header.source()), " bytes need ", expected));
      }
      payload = std::move(*header.mutable_source_data());
    } else {
      v1::RegisterRequest message;
      auto next_chunk = [&]() -> absl::StatusOr<const v1::CloudChunk*> {
        if (!stream_->Read(&message)) {
          if (ctx_->IsCancelled()) return absl::CancelledError("client cancelled the call");
          return nullptr;
        }
        if (!message.has_source_chunk()) {
          return absl::InvalidArgumentError("source_chunk: expected a chunk, got another header");
        }
        return &message.source_chunk();
      };
      auto chunks =
          ReadChunkedPayload(expected, c_.config.max_chunk_bytes, "source_chunk", next_chunk);
      if (!chunks.ok()) return chunks.status();
      payload = *std::move(chunks);
    }
    return wire::DecodeCloud(header.source(), payload, "source");
  }

  // Forwards the newest progress until the job ends. A blocked Write (slow reader) just means
  // intermediate iterations are skipped: the job overwrites its report slot meanwhile.
  absl::Status RelayUntilDone(RegistrationJob& job) {
    for (;;) {
      const RegistrationJob::Update update = job.WaitForUpdate(kPollInterval);
      if (ctx_->IsCancelled()) return ClientGone(job);
      if (update.progress) {
        v1::RegisterResponse response;
        wire::ToProto(*update.progress, response.mutable_progress());
        if (!stream_->Write(response)) return ClientGone(job);
      }
      if (update.done) return SendResult(job);
    }
  }

  absl::Status SendResult(const RegistrationJob& job) {
    const absl::StatusOr<RegistrationOutcome>& outcome = job.outcome();
    if (!outcome.ok()) return outcome.status();
    const RegistrationResult& result = outcome->result;
    scope_->add_detail(absl::StrFormat(
        "iterations=%d termination=%s queue_ms=%.1f", result.iterations,
        std::string(TerminationName(result.termination)), outcome->queue_seconds * 1e3));
    if (result.termination == Termination::kCancelled) {
      return job.StoppedStatus(result.iterations);
    }
    v1::RegisterResponse response;
    v1::Result* out = response.mutable_result();
    wire::ToProto(result, out);
    out->mutable_timings()->set_queue_seconds(outcome->queue_seconds);
    if (outcome->ground_truth_error) {
      const PoseError& e = *outcome->ground_truth_error;
      v1::GroundTruthError* gt = out->mutable_ground_truth_error();
      gt->set_rmse_d(e.rmse_d);
      gt->set_success(e.success);
      gt->set_rotation_error_deg(e.rotation_deg);
      gt->set_translation_error_d(e.translation_d);
    }
    if (!stream_->Write(response)) return absl::CancelledError("client went away");
    return absl::OkStatus();
  }

  // Stops the job (it frees its worker within one iteration) and reports why the call ended.
  absl::Status ClientGone(RegistrationJob& job) {
    job.Cancel();
    if (std::chrono::system_clock::now() >= ctx_->deadline()) {
      return absl::DeadlineExceededError("deadline exceeded; registration cancelled");
    }
    return absl::CancelledError("client cancelled; registration cancelled");
  }

  ServiceContext& c_;
  grpc::ServerContext* ctx_;
  RegisterStream* stream_;
  RpcScope* scope_;
};

class RegistrationServiceImpl final : public v1::RegistrationService::Service {
 public:
  explicit RegistrationServiceImpl(ServiceContext& c) : c_(c) {}

  grpc::Status Register(grpc::ServerContext* ctx, RegisterStream* stream) override {
    RpcScope scope(c_, "Register");
    return scope.Finish(RegisterHandler(c_, ctx, stream, &scope).Run());
  }

 private:
  ServiceContext& c_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewRegistrationService(ServiceContext& context) {
  return std::make_unique<RegistrationServiceImpl>(context);
}

}  // namespace mlsreg::server
