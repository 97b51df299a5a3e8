// RegistrationService.Register on gRPC's callback API. One call, in order:
//  1. admission (token, draining, per-peer stream limit: StreamingCall);
//  2. the header, validated whole: ids, method, parameters, transforms, the source's declared
//     size, the target (pinned when resident) and what the method needs of it;
//  3. room in the job queue and in the in-flight budget for the source, checked before any data is
//     read, so a request that cannot run is refused before it is transferred;
//  4. the source: inline in the header or in chunks, the buffer growing as data arrives;
//  5. the job on a worker; its progress is relayed as the client reads (latest wins), then the
//     result. A client that cancels, goes idle or misses its deadline cancels the job.
#include <chrono>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "grpcpp/grpcpp.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"
#include "server/align_scans_call.h"
#include "server/ids.h"
#include "server/job_call.h"
#include "server/registration_job.h"
#include "server/services.h"
#include "server/streaming_call.h"

namespace mlsreg::server {
namespace {

// A registration needs at least this many source points (the library's own minimum).
constexpr std::uint64_t kMinSourcePoints = 3;

using RegisterReactor = grpc::ServerBidiReactor<v1::RegisterRequest, v1::RegisterResponse>;

class RegisterCall final
    : public JobCall<v1::RegisterRequest, v1::RegisterResponse, RegistrationJob> {
 public:
  RegisterCall(ServiceContext& c, grpc::CallbackServerContext* ctx) : JobCall(c, ctx, "Register") {}

  void Begin() { ReadNext("the header"); }

  void OnReadDone(bool ok) override {
    EndWait();
    if (finished()) return;
    absl::Status status;
    if (!ok) {
      status = ctx_->IsCancelled() ? ClientGone()
               : payload_
                   ? payload_->EndedEarly()
                   : absl::InvalidArgumentError("header: the stream ended before the header");
    } else {
      status = payload_ ? OnChunk() : OnHeader();
    }
    if (status.ok() && !(payload_ && payload_->complete()) && !inline_source_) {
      ReadNext("a source chunk");
      return;
    }
    if (status.ok()) status = Submit();
    if (!status.ok()) FinishWith(status);
  }

 private:
  // Steps 2 and 3.
  absl::Status OnHeader() {
    if (!request_.has_header()) {
      return absl::InvalidArgumentError("header: the first message must be the header");
    }
    v1::RegisterHeader& header = *request_.mutable_header();
    if (absl::Status s = ParseHeader(header); !s.ok()) return s;
    auto expected = wire::CheckCloudHeader(header.source(), c_.config.max_points, "header.source");
    if (!expected.ok()) return expected.status();
    if (header.source().point_count() < kMinSourcePoints) {
      return absl::InvalidArgumentError(
          absl::StrCat("header.source.point_count: a registration needs at least ",
                       kMinSourcePoints, " points (got ", header.source().point_count(), ")"));
    }
    // An unknown target is reported before the source is transferred. A resident target is
    // pinned from here on, so it cannot be evicted while this request waits in the queue.
    auto info = c_.cache.Info(input_.target_id);
    if (!info.ok()) return info.status();
    if (NeedsOrganisedTarget(input_.options.method) && !info->has_intrinsics) {
      return OrganisedTargetRequired(input_.options.method);
    }
    auto target = c_.cache.Peek(input_.target_id);
    if (!target.ok()) return target.status();
    input_.target = *std::move(target);

    // Refused now, before the data is sent, when it could not run: no room in the queue or in
    // the in-flight budget (payload + decoded cloud). Nothing is held while the data comes.
    if (absl::Status s = c_.jobs.CheckRoom(); !s.ok()) return s;
    decoded_bytes_ =
        header.source().point_count() * sizeof(Vec3) * (header.source().has_normals() ? 2 : 1);
    if (absl::Status s = c_.inflight.Check(*expected + decoded_bytes_, "header.source"); !s.ok()) {
      return s;
    }

    source_header_ = header.source();
    if (!header.source_data().empty()) {
      if (header.source_data().size() != *expected) {
        return absl::InvalidArgumentError(
            absl::StrCat("header.source_data: ", header.source_data().size(), " bytes, but ",
                         header.source().point_count(), " points of ",
                         wire::RecordBytes(header.source()), " bytes need ", *expected));
      }
      if (absl::Status s = lease_->Grow(*expected, "header.source_data"); !s.ok()) return s;
      inline_source_ = std::move(*header.mutable_source_data());
      return absl::OkStatus();
    }
    payload_.emplace(*expected, c_.config.max_chunk_bytes, "source_chunk");
    return absl::OkStatus();
  }

  // Ids, method, parameters and transforms.
  absl::Status ParseHeader(const v1::RegisterHeader& header) {
    input_.request_id = header.request_id().empty() ? NewRequestId() : header.request_id();
    if (absl::Status s = ValidateRequestId(input_.request_id, "header.request_id"); !s.ok()) {
      return s;
    }
    scope_.set_request_id(input_.request_id);
    if (absl::Status s = ValidateTargetId(header.target_id(), "header.target_id"); !s.ok()) {
      return s;
    }
    input_.target_id = header.target_id();
    scope_.set_target_id(input_.target_id);
    auto options = wire::OptionsFromProto(header.method(), header.parameters());
    if (!options.ok()) return options.status();
    input_.options = *options;
    input_.threads = c_.config.job_threads;
    if (header.has_initial_transform()) {
      auto m = wire::FromProto(header.initial_transform(), "header.initial_transform");
      if (!m.ok()) return m.status();
      input_.initial = *m;
    }
    if (header.has_ground_truth()) {
      auto m = wire::FromProto(header.ground_truth(), "header.ground_truth");
      if (!m.ok()) return m.status();
      input_.ground_truth = *m;
    }
    method_name_ = std::string(wire::MethodName(header.method()));
    return absl::OkStatus();
  }

  absl::Status OnChunk() {
    if (!request_.has_source_chunk()) {
      return absl::InvalidArgumentError("source_chunk: expected a chunk, got another header");
    }
    if (absl::Status s = lease_->Grow(request_.source_chunk().data().size(), "source_chunk");
        !s.ok()) {
      return s;
    }
    return payload_->Append(request_.source_chunk());
  }

  // Step 5: decode, queue the job (JobCall relays it).
  absl::Status Submit() {
    std::string payload = inline_source_ ? std::move(*inline_source_) : payload_->Release();
    if (absl::Status s = lease_->Grow(decoded_bytes_, "source"); !s.ok()) return s;
    auto source = wire::DecodeCloud(source_header_, payload, "source");
    if (!source.ok()) return source.status();
    lease_->Shrink(payload.size());
    std::string().swap(payload);  // the decoded cloud is what stays in flight
    if (absl::Status s = CheckCoordinateRange(*source); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
    }
    input_.source = *std::move(source);
    input_.deadline = ctx_->deadline();
    scope_.add_detail(
        absl::StrCat("method=", method_name_, " source_points=", input_.source.size()));
    const std::string request_id = input_.request_id;
    return Queue(
        std::make_shared<RegistrationJob>(std::move(input_), &c_.cache, &c_.state.stop_flag()),
        request_id, lease_);
  }

  // The newest progress (latest wins), then the result.
  absl::StatusOr<Next> NextFromJob(RegistrationJob& job) override {
    const RegistrationJob::Update update = job.WaitForUpdate(std::chrono::milliseconds(0));
    if (update.progress) {
      out_.Clear();
      wire::ToProto(*update.progress, out_.mutable_progress());
      return Next::kWrite;
    }
    if (!update.done) return Next::kNothing;
    if (absl::Status s = FillResult(job); !s.ok()) return s;
    return Next::kResult;
  }

  // The result message into out_, or the status the call ends with. Requires mutex_.
  absl::Status FillResult(const RegistrationJob& job) {
    const absl::StatusOr<RegistrationOutcome>& outcome = job.outcome();
    if (!outcome.ok()) return outcome.status();
    const RegistrationResult& result = outcome->result;
    c_.metrics.RecordRegistration(method_name_, TerminationName(result.termination),
                                  result.timings.total);
    scope_.add_detail(absl::StrFormat(
        "iterations=%d termination=%s queue_ms=%.1f", result.iterations,
        std::string(TerminationName(result.termination)), outcome->queue_seconds * 1e3));
    if (result.termination == Termination::kCancelled) return job.StoppedStatus(result.iterations);
    out_.Clear();
    v1::Result* out = out_.mutable_result();
    wire::ToProto(result, out);
    out->mutable_timings()->set_queue_seconds(outcome->queue_seconds);
    if (outcome->ground_truth_error) {
      wire::ToProto(*outcome->ground_truth_error, out->mutable_ground_truth_error());
    }
    return absl::OkStatus();
  }

  RegistrationInput input_;
  std::string method_name_;
  v1::CloudHeader source_header_;
  std::optional<std::string> inline_source_;
  std::optional<wire::PayloadAssembler> payload_;
  std::uint64_t decoded_bytes_ = 0;
  // The bytes this call holds: its data as it arrives, then its decoded source; shared with the
  // job, so held until it ends.
  std::shared_ptr<InFlightBudget::Lease> lease_ =
      std::make_shared<InFlightBudget::Lease>(&c_.inflight);
};

class RegistrationServiceImpl final : public v1::RegistrationService::CallbackService {
 public:
  explicit RegistrationServiceImpl(ServiceContext& c) : c_(c) {}

  RegisterReactor* Register(grpc::CallbackServerContext* ctx) override {
    return StreamingCall<RegisterReactor>::Launch<RegisterCall>(c_, ctx);
  }

  AlignScansReactor* AlignScans(grpc::CallbackServerContext* ctx) override {
    return StartAlignScans(c_, ctx);
  }

 private:
  ServiceContext& c_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewRegistrationService(ServiceContext& context) {
  return std::make_unique<RegistrationServiceImpl>(context);
}

}  // namespace mlsreg::server
