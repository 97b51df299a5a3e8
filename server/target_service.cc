// TargetService: upload (client-streamed, header then chunks), inspect, list and delete targets.
#include <atomic>
#include <chrono>

#include "absl/strings/str_cat.h"
#include "grpcpp/grpcpp.h"
#include "mlsreg/core/cloud_digest.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"
#include "server/ids.h"
#include "server/rpc_scope.h"
#include "server/services.h"
#include "server/streaming_call.h"

namespace mlsreg::server {
namespace {

constexpr int kDefaultPageSize = 100;
constexpr int kMaxPageSize = 1000;

// "sha256:" followed by 64 lower-case hex digits, the form CloudDigest writes.
bool IsDigest(std::string_view text) {
  constexpr std::string_view kPrefix = "sha256:";
  if (text.size() != kPrefix.size() + 64 || text.substr(0, kPrefix.size()) != kPrefix) return false;
  for (char c : text.substr(kPrefix.size())) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

// The decoded cloud an upload becomes (points, normals), held in flight until it is built.
std::uint64_t DecodedBytes(const v1::CloudHeader& cloud) {
  return cloud.point_count() * sizeof(Vec3) * (cloud.has_normals() ? 2 : 1);
}

// One CreateTarget call on gRPC's callback API: admission (StreamingCall), the header (id,
// declared size, digest, cache fit), room in the job queue and the in-flight budget checked
// before any data is read, the chunks (the buffer and the bytes counted grow as they arrive),
// then on a worker:
// decode, digest, build (cancellable) and insert.
using CreateTargetReactor = grpc::ServerReadReactor<v1::CreateTargetRequest>;

class CreateTargetCall final : public StreamingCall<CreateTargetReactor> {
 public:
  CreateTargetCall(ServiceContext& c, grpc::CallbackServerContext* ctx, v1::Target* response)
      : StreamingCall(c, ctx, "CreateTarget"), response_(response) {}

  void Begin() { ReadNext("the header"); }

  void OnReadDone(bool ok) override {
    EndWait();
    if (finished()) return;
    if (!payload_) {
      absl::Status status =
          ok ? OnHeader()
             : absl::InvalidArgumentError("header: the stream ended before the header");
      if (!status.ok()) {
        FinishWith(status);
      } else if (payload_) {
        ReadNext("a chunk");
      }  // else OnHeader finished the call (same content already stored)
      return;
    }
    if (payload_->complete()) {  // one read past the data: the stream must end here
      if (ok) {
        FinishWith(absl::InvalidArgumentError(absl::StrCat(
            "chunk: more messages after the declared ", payload_->received(), " bytes")));
      } else {
        Build();
      }
      return;
    }
    absl::Status status;
    if (!ok) {
      status = ctx_->IsCancelled() ? ClientGone() : payload_->EndedEarly();
    } else if (!request_.has_chunk()) {
      status = absl::InvalidArgumentError("chunk: expected a chunk, got another header");
    } else {
      status = lease_->Grow(request_.chunk().data().size(), "chunk");
      if (status.ok()) status = payload_->Append(request_.chunk());
    }
    if (!status.ok()) {
      FinishWith(status);
      return;
    }
    ReadNext(payload_->complete() ? "the end of the upload" : "a chunk");
  }

 private:
  void ReadNext(const char* what) {
    BeginWait(what);
    StartUnlessFinished([this] { StartRead(&request_); });
  }

  void Abandoned() override { cancelled_->store(true); }

  absl::Status OnHeader() {
    if (!request_.has_header()) {
      return absl::InvalidArgumentError("header: the first message must be the header");
    }
    header_ = std::move(*request_.mutable_header());
    if (absl::Status s = ValidateTargetId(header_.target_id(), "header.target_id"); !s.ok()) {
      return s;
    }
    scope_.set_target_id(header_.target_id());
    if (!header_.content_digest().empty() && !IsDigest(header_.content_digest())) {
      return absl::InvalidArgumentError(
          "header.content_digest: must be \"sha256:\" + 64 hex digits (Target.content_digest)");
    }
    auto expected = wire::CheckCloudHeader(header_.cloud(), c_.config.max_points, "header.cloud");
    if (!expected.ok()) return expected.status();
    auto existing = c_.cache.CheckCanCreate(
        header_.target_id(), wire::EstimatedTargetBytes(header_.cloud()), header_.content_digest());
    if (!existing.ok()) return existing.status();
    if (existing->has_value()) {  // the same content is there: nothing to send
      scope_.add_detail("unchanged=true");
      FinishWith(absl::OkStatus(), [&] { wire::ToProto(**existing, response_); });
      return absl::OkStatus();
    }
    // Refused now, before the data is sent, when it could not be built: no room in the queue
    // or in the in-flight budget. Nothing is held while the data comes.
    if (absl::Status s = c_.jobs.CheckRoom(); !s.ok()) return s;
    if (absl::Status s =
            c_.inflight.Check(*expected + DecodedBytes(header_.cloud()), "header.cloud");
        !s.ok()) {
      return s;
    }
    payload_.emplace(*expected, c_.config.max_chunk_bytes, "chunk");
    return absl::OkStatus();
  }

  // On a worker: decode, digest, build, insert; the call ends when it is done.
  void Build() {
    auto payload = std::make_shared<std::string>(payload_->Release());
    if (absl::Status s = lease_->Grow(DecodedBytes(header_.cloud()), "cloud"); !s.ok()) {
      FinishWith(s);
      return;
    }
    std::weak_ptr<CreateTargetCall> weak = std::static_pointer_cast<CreateTargetCall>(self());
    auto submitted = c_.jobs.TrySubmit(
        [this_call = weak, payload, lease = lease_, header = header_, cancelled = cancelled_,
         &cache = c_.cache] {
          absl::StatusOr<TargetInfo> built = BuildAndInsert(cache, header, *payload, *cancelled);
          payload->clear();
          payload->shrink_to_fit();
          // The data is freed (the cloud is in the cache or gone): give its bytes back before
          // the client hears of it, so a finished upload holds nothing in flight.
          lease->Shrink(lease->bytes());
          if (auto call = this_call.lock()) call->Built(std::move(built));
        },
        [this_call = weak](absl::Status s) {
          if (auto call = this_call.lock()) call->Built(std::move(s));
        });
    if (!submitted.ok()) FinishWith(submitted.status());
  }

  static absl::StatusOr<TargetInfo> BuildAndInsert(TargetCache& cache,
                                                   const v1::CreateTargetHeader& header,
                                                   const std::string& payload,
                                                   const std::atomic<bool>& cancelled) {
    auto cloud = wire::DecodeCloud(header.cloud(), payload, "cloud");
    if (!cloud.ok()) return cloud.status();
    const std::string digest = CloudDigest(*cloud);
    if (!header.content_digest().empty() && header.content_digest() != digest) {
      return absl::InvalidArgumentError(absl::StrCat("header.content_digest: declared ",
                                                     header.content_digest(),
                                                     " but the data received has ", digest));
    }
    return cache.Create(header.target_id(), *std::move(cloud), digest,
                        [&] { return cancelled.load(); });
  }

  void Built(absl::StatusOr<TargetInfo> info) {
    if (!info.ok()) {
      FinishWith(absl::IsCancelled(info.status()) ? ClientGone() : info.status());
      return;
    }
    scope_.add_detail(absl::StrCat("points=", info->point_count));
    FinishWith(absl::OkStatus(), [&] { wire::ToProto(*info, response_); });
  }

  v1::Target* const response_;  // owned by gRPC; written only when this call finishes it
  v1::CreateTargetRequest request_;
  v1::CreateTargetHeader header_;
  std::optional<wire::PayloadAssembler> payload_;
  // The bytes this call holds: its data as it arrives, then its decoded cloud; shared with the
  // build, which gives them back when it ends.
  std::shared_ptr<InFlightBudget::Lease> lease_ =
      std::make_shared<InFlightBudget::Lease>(&c_.inflight);
  std::shared_ptr<std::atomic<bool>> cancelled_ = std::make_shared<std::atomic<bool>>(false);
};

// CreateTarget streams on the callback API; the unary RPCs stay on the sync server's threads.
class TargetServiceImpl final
    : public v1::TargetService::WithCallbackMethod_CreateTarget<v1::TargetService::Service> {
 public:
  explicit TargetServiceImpl(ServiceContext& c) : c_(c) {}

  CreateTargetReactor* CreateTarget(grpc::CallbackServerContext* ctx,
                                    v1::Target* response) override {
    return StreamingCall<CreateTargetReactor>::Launch<CreateTargetCall>(c_, ctx, response);
  }

  grpc::Status GetTarget(grpc::ServerContext* ctx, const v1::GetTargetRequest* request,
                         v1::Target* response) override {
    RpcScope scope(c_, "GetTarget", ctx, kReadRpc);
    return scope.Run([&]() -> absl::Status {
      if (absl::Status s = ValidateTargetId(request->target_id(), "target_id"); !s.ok()) return s;
      scope.set_target_id(request->target_id());
      auto info = c_.cache.Info(request->target_id());
      if (!info.ok()) return info.status();
      wire::ToProto(*info, response);
      return absl::OkStatus();
    });
  }

  grpc::Status ListTargets(grpc::ServerContext* ctx, const v1::ListTargetsRequest* request,
                           v1::ListTargetsResponse* response) override {
    RpcScope scope(c_, "ListTargets", ctx, kReadRpc);
    return scope.Run([&]() -> absl::Status {
      if (request->page_size() < 0) {
        return absl::InvalidArgumentError("page_size: must be >= 0 (0: server default)");
      }
      // The page token is the last id of the previous page (ids are sorted), so it stays valid
      // when targets come and go between pages.
      if (!request->page_token().empty()) {
        if (absl::Status s = ValidateTargetId(request->page_token(), "page_token"); !s.ok()) {
          return s;
        }
      }
      const int size = request->page_size() == 0 ? kDefaultPageSize
                                                 : std::min(request->page_size(), kMaxPageSize);
      bool more = false;
      for (const TargetInfo& info : c_.cache.List(request->page_token(), size, &more)) {
        wire::ToProto(info, response->add_targets());
      }
      if (more && response->targets_size() > 0) {
        response->set_next_page_token(response->targets(response->targets_size() - 1).target_id());
      }
      return absl::OkStatus();
    });
  }

  grpc::Status DeleteTarget(grpc::ServerContext* ctx, const v1::DeleteTargetRequest* request,
                            v1::DeleteTargetResponse*) override {
    RpcScope scope(c_, "DeleteTarget", ctx, kAdminRpc);
    return scope.Run([&]() -> absl::Status {
      if (absl::Status s = ValidateTargetId(request->target_id(), "target_id"); !s.ok()) return s;
      scope.set_target_id(request->target_id());
      return c_.cache.Erase(request->target_id());
    });
  }

 private:
  ServiceContext& c_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewTargetService(ServiceContext& context) {
  return std::make_unique<TargetServiceImpl>(context);
}

}  // namespace mlsreg::server
