// RegistrationService.AlignScans. One call, in order:
//  1. admission (token, draining, per-peer stream limit: StreamingCall);
//  2. the header, validated whole: ids, the scan count, the options and initial poses, every
//     scan (a known target, pinned when resident, or an uploaded cloud's declared size) and what
//     the edge method needs of them;
//  3. room in the job queue, and in the in-flight budget for the uploaded scans as data and as
//     built targets, checked before any data is read;
//  4. the uploaded scans' data in chunks, one payload, the buffer growing as data arrives;
//  5. one job on a worker (its edges on job_threads threads); every finished edge is relayed,
//     then the result. A client that cancels, goes idle or misses its deadline cancels the job.
#include "server/align_scans_call.h"

#include <set>

#include "absl/strings/str_cat.h"
#include "mlsreg/wire/convert.h"
#include "server/align_job.h"
#include "server/ids.h"
#include "server/job_call.h"

namespace mlsreg::server {
namespace {

// An uploaded scan needs at least this many points (a target's minimum).
constexpr std::uint64_t kMinScanPoints = 10;

class AlignScansCall final
    : public JobCall<v1::AlignScansRequest, v1::AlignScansResponse, AlignJob> {
 public:
  AlignScansCall(ServiceContext& c, grpc::CallbackServerContext* ctx)
      : JobCall(c, ctx, "AlignScans") {}

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
      status = have_header_ ? OnChunk() : OnHeader();
    }
    if (status.ok() && payload_ && !payload_->complete()) {
      ReadNext("a scan chunk");
      return;
    }
    if (status.ok()) status = Submit();
    if (!status.ok()) FinishWith(status);
  }

 private:
  struct Upload {
    int scan = 0;
    v1::CloudHeader header;
    std::uint64_t bytes = 0;
  };

  // Steps 2 and 3.
  absl::Status OnHeader() {
    if (!request_.has_header()) {
      return absl::InvalidArgumentError("header: the first message must be the header");
    }
    have_header_ = true;
    const v1::AlignScansHeader& header = request_.header();
    input_.request_id = header.request_id().empty() ? NewRequestId() : header.request_id();
    if (absl::Status s = ValidateRequestId(input_.request_id, "header.request_id"); !s.ok()) {
      return s;
    }
    scope_.set_request_id(input_.request_id);
    const int n = header.scans_size();
    if (n < 2 || n > kMaxAlignScans) {
      return absl::InvalidArgumentError(
          absl::StrCat("header.scans: need 2 to ", kMaxAlignScans, " scans, got ", n));
    }
    auto options = wire::AlignOptionsFromProto(header);
    if (!options.ok()) return options.status();
    input_.options = *std::move(options);
    input_.options.threads = c_.config.job_threads;
    if (absl::Status s = ValidateAlignOptions(n, input_.options); !s.ok()) return s;
    const bool organised = NeedsOrganisedTarget(input_.options.edge.method);

    std::uint64_t payload_bytes = 0, target_bytes = 0;
    std::set<std::string> ids;
    for (int i = 0; i < n; ++i) {
      const v1::AlignScan& scan = header.scans(i);
      const std::string field = absl::StrCat("header.scans[", i, "]");
      AlignScanInput in;
      if (scan.scan_case() == v1::AlignScan::kTargetId) {
        if (absl::Status s = ValidateTargetId(scan.target_id(), field + ".target_id"); !s.ok()) {
          return s;
        }
        if (!ids.insert(scan.target_id()).second) {
          return absl::InvalidArgumentError(absl::StrCat(field, ".target_id: \"", scan.target_id(),
                                                         "\" is given twice; each scan once"));
        }
        auto info = c_.cache.Info(scan.target_id());
        if (!info.ok()) {
          return absl::Status(info.status().code(),
                              absl::StrCat(field, ".target_id: ", info.status().message()));
        }
        if (organised && !info->has_intrinsics) {
          return absl::InvalidArgumentError(absl::StrCat(
              field, ": ", OrganisedTargetRequired(input_.options.edge.method).message()));
        }
        auto target = c_.cache.Peek(scan.target_id());  // pinned from here on when resident
        if (!target.ok()) return target.status();
        in.target_id = scan.target_id();
        in.target = *std::move(target);
      } else if (scan.scan_case() == v1::AlignScan::kCloud) {
        auto expected =
            wire::CheckCloudHeader(scan.cloud(), c_.config.max_points, field + ".cloud");
        if (!expected.ok()) return expected.status();
        if (scan.cloud().point_count() < kMinScanPoints) {
          return absl::InvalidArgumentError(
              absl::StrCat(field, ".cloud.point_count: a scan needs at least ", kMinScanPoints,
                           " points (got ", scan.cloud().point_count(), ")"));
        }
        if (organised && !scan.cloud().has_intrinsics()) {
          return absl::InvalidArgumentError(absl::StrCat(
              field, ": ", OrganisedTargetRequired(input_.options.edge.method).message()));
        }
        uploads_.push_back({i, scan.cloud(), *expected});
        payload_bytes += *expected;
        target_bytes += wire::EstimatedTargetBytes(scan.cloud());
      } else {
        return absl::InvalidArgumentError(
            absl::StrCat(field, ": set target_id (a cached target) or cloud (data follows)"));
      }
      input_.scans.push_back(std::move(in));
    }
    scope_.add_detail(absl::StrCat("scans=", n, " uploaded=", uploads_.size(),
                                   " pairs=", std::string(PairPolicyName(input_.options.pairs))));

    // Refused now, before any data is sent, when it could not run. The uploaded scans are
    // charged as data and then as built targets (their estimate), until the job ends.
    if (absl::Status s = c_.jobs.CheckRoom(); !s.ok()) return s;
    target_bytes_ = target_bytes;
    if (absl::Status s = c_.inflight.Check(payload_bytes + target_bytes, "header.scans"); !s.ok()) {
      return s;
    }
    if (payload_bytes > 0) payload_.emplace(payload_bytes, c_.config.max_chunk_bytes, "scan_chunk");
    return absl::OkStatus();
  }

  absl::Status OnChunk() {
    if (!request_.has_scan_chunk()) {
      return absl::InvalidArgumentError("scan_chunk: expected a chunk, got another header");
    }
    if (absl::Status s = lease_->Grow(request_.scan_chunk().data().size(), "scan_chunk"); !s.ok()) {
      return s;
    }
    return payload_->Append(request_.scan_chunk());
  }

  // Step 5: decode the uploads, queue the job (JobCall relays it).
  absl::Status Submit() {
    if (absl::Status s = lease_->Grow(target_bytes_, "scans"); !s.ok()) return s;
    if (payload_) {
      std::string payload = payload_->Release();
      std::uint64_t offset = 0;
      for (const Upload& up : uploads_) {
        const std::string field = absl::StrCat("scans[", up.scan, "]");
        auto cloud =
            wire::DecodeCloud(up.header, std::string_view(payload).substr(offset, up.bytes), field);
        if (!cloud.ok()) return cloud.status();
        if (absl::Status s = CheckCoordinateRange(*cloud); !s.ok()) {
          return absl::InvalidArgumentError(absl::StrCat(field, ": ", s.message()));
        }
        input_.scans[up.scan].cloud = *std::move(cloud);
        offset += up.bytes;
      }
      lease_->Shrink(payload.size());  // the targets' estimate covers the decoded clouds
    }
    input_.deadline = ctx_->deadline();
    const std::string request_id = input_.request_id;
    return Queue(std::make_shared<AlignJob>(std::move(input_), &c_.cache, &c_.state.stop_flag()),
                 request_id, lease_);
  }

  // Every finished edge, then the result.
  absl::StatusOr<Next> NextFromJob(AlignJob& job) override {
    const AlignJob::Update update = job.NextUpdate();
    if (update.edge) {
      out_.Clear();
      v1::AlignProgress* progress = out_.mutable_progress();
      wire::ToProto(update.edge->edge, progress->mutable_edge());
      progress->set_edges_done(update.edge->done);
      progress->set_edges_total(update.edge->total);
      progress->set_elapsed_seconds(update.edge->elapsed_seconds);
      return Next::kWrite;
    }
    if (!update.done) return Next::kNothing;
    if (absl::Status s = FillResult(job); !s.ok()) return s;
    return Next::kResult;
  }

  // The result message into out_, or the status the call ends with. Requires mutex_.
  absl::Status FillResult(const AlignJob& job) {
    const absl::StatusOr<AlignOutcome>& outcome = job.outcome();
    if (!outcome.ok()) return outcome.status();
    out_.Clear();
    v1::AlignScansResult* out = out_.mutable_result();
    wire::ToProto(outcome->result, out);
    out->set_queue_seconds(outcome->queue_seconds);
    scope_.add_detail(absl::StrCat("edges=", outcome->result.edges.size()));
    return absl::OkStatus();
  }

  bool have_header_ = false;
  AlignInput input_;
  std::vector<Upload> uploads_;
  std::optional<wire::PayloadAssembler> payload_;
  std::uint64_t target_bytes_ = 0;
  // The bytes this call holds: uploaded data as it arrives, then the uploaded scans' targets
  // (estimated); shared with the job, so held until it ends.
  std::shared_ptr<InFlightBudget::Lease> lease_ =
      std::make_shared<InFlightBudget::Lease>(&c_.inflight);
};

}  // namespace

AlignScansReactor* StartAlignScans(ServiceContext& c, grpc::CallbackServerContext* ctx) {
  return StreamingCall<AlignScansReactor>::Launch<AlignScansCall>(c, ctx);
}

}  // namespace mlsreg::server
