// TargetService: upload (client-streamed, header then chunks), inspect, list and delete targets.
#include <chrono>

#include "absl/strings/str_cat.h"
#include "grpcpp/grpcpp.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"
#include "server/chunked_payload.h"
#include "server/ids.h"
#include "server/pending_result.h"
#include "server/rpc_scope.h"
#include "server/services.h"

namespace mlsreg::server {
namespace {

constexpr std::chrono::milliseconds kPollInterval{100};
constexpr int kDefaultPageSize = 100;
constexpr int kMaxPageSize = 1000;

// A lower bound of Target::MemoryBytes for a cloud: points, normals if any, and the per-point
// normal, curvature and validity the build adds (the kd-tree comes on top). Checked before any
// data is read, so a client learns that a target can never fit without sending it.
std::uint64_t MinTargetBytes(const v1::CloudHeader& cloud) {
  const std::uint64_t per_point = sizeof(Vec3) * (cloud.has_normals() ? 3 : 2) + sizeof(double) + 1;
  return cloud.point_count() * per_point;
}

void ToProto(const TargetInfo& info, v1::Target* out) {
  out->set_target_id(info.id);
  out->set_state(info.state == TargetState::kReady ? v1::TARGET_STATE_READY
                                                   : v1::TARGET_STATE_STORED);
  out->set_point_count(info.point_count);
  out->set_memory_bytes(info.memory_bytes);
  out->set_sampling_distance(info.sampling_distance);
  out->set_build_seconds(info.build_seconds);
  out->set_registrations(info.registrations);
}

// One CreateTarget call: header, chunks, decode, build on the pool, insert.
class CreateTargetHandler {
 public:
  CreateTargetHandler(ServiceContext& c, grpc::ServerContext* ctx,
                      grpc::ServerReader<v1::CreateTargetRequest>* reader, RpcScope* scope)
      : c_(c), ctx_(ctx), reader_(reader), scope_(scope) {}

  absl::Status Run(v1::Target* response) {
    if (absl::Status s = c_.auth.Check(*ctx_, Access::kUser); !s.ok()) return s;
    if (!c_.state.accepting()) return absl::UnavailableError("server is shutting down");
    v1::CreateTargetHeader header;
    auto expected = ReadHeader(&header);
    if (!expected.ok()) return expected.status();
    auto cloud = ReadCloud(header.cloud(), *expected);
    if (!cloud.ok()) return cloud.status();
    auto target = BuildOnPool(*std::move(cloud));
    if (!target.ok()) return target.status();
    auto info = c_.cache.Insert(header.target_id(), *std::move(target));
    if (!info.ok()) return info.status();
    scope_->add_detail(absl::StrCat("points=", info->point_count));
    ToProto(*info, response);
    return absl::OkStatus();
  }

 private:
  // The first message, validated before any point data is accepted. Returns the payload size.
  absl::StatusOr<std::uint64_t> ReadHeader(v1::CreateTargetHeader* header) {
    v1::CreateTargetRequest first;
    if (!reader_->Read(&first)) {
      return absl::InvalidArgumentError("header: the stream ended before the header");
    }
    if (!first.has_header()) {
      return absl::InvalidArgumentError("header: the first message must be the header");
    }
    *header = std::move(*first.mutable_header());
    if (absl::Status s = ValidateTargetId(header->target_id(), "header.target_id"); !s.ok()) {
      return s;
    }
    scope_->set_target_id(header->target_id());
    auto expected = wire::CheckCloudHeader(header->cloud(), c_.config.max_points, "header.cloud");
    if (!expected.ok()) return expected.status();
    if (absl::Status s =
            c_.cache.CheckCanCreate(header->target_id(), MinTargetBytes(header->cloud()));
        !s.ok()) {
      return s;
    }
    return expected;
  }

  absl::StatusOr<PointCloud> ReadCloud(const v1::CloudHeader& header, std::uint64_t expected) {
    auto payload = ReadPayload(expected);
    if (!payload.ok()) return payload.status();
    return wire::DecodeCloud(header, *payload, "cloud");
  }

  // The chunks after the header; nothing may follow the declared bytes.
  absl::StatusOr<std::string> ReadPayload(std::uint64_t expected) {
    v1::CreateTargetRequest message;
    auto next_chunk = [&]() -> absl::StatusOr<const v1::CloudChunk*> {
      if (!reader_->Read(&message)) {
        if (ctx_->IsCancelled()) return absl::CancelledError("client cancelled the upload");
        return nullptr;
      }
      if (!message.has_chunk()) {
        return absl::InvalidArgumentError("chunk: expected a chunk, got another header");
      }
      return &message.chunk();
    };
    auto payload = ReadChunkedPayload(expected, c_.config.max_chunk_bytes, "chunk", next_chunk);
    if (!payload.ok()) return payload.status();
    if (reader_->Read(&message)) {
      return absl::InvalidArgumentError(
          absl::StrCat("chunk: more messages after the declared ", expected, " bytes"));
    }
    return payload;
  }

  // Building (kd-tree, normals, curvature) is CPU work: it runs on the pool; this thread waits
  // and gives up when the client does.
  absl::StatusOr<std::shared_ptr<const Target>> BuildOnPool(PointCloud cloud) {
    using BuildResult = absl::StatusOr<std::shared_ptr<const Target>>;
    auto pending = std::make_shared<PendingResult<BuildResult>>();
    auto input = std::make_shared<PointCloud>(std::move(cloud));
    auto submitted =
        c_.jobs.TrySubmit([pending, input] { pending->Set(Target::Build(std::move(*input))); });
    if (!submitted.ok()) return submitted.status();
    for (;;) {
      if (std::optional<BuildResult> built = pending->WaitFor(kPollInterval)) {
        if (!built->ok()) {
          return absl::InvalidArgumentError(
              absl::StrCat("cloud: cannot build the target: ", built->status().message()));
        }
        return *std::move(built);
      }
      if (ctx_->IsCancelled()) return absl::CancelledError("client cancelled the upload");
    }
  }

  ServiceContext& c_;
  grpc::ServerContext* ctx_;
  grpc::ServerReader<v1::CreateTargetRequest>* reader_;
  RpcScope* scope_;
};

class TargetServiceImpl final : public v1::TargetService::Service {
 public:
  explicit TargetServiceImpl(ServiceContext& c) : c_(c) {}

  grpc::Status CreateTarget(grpc::ServerContext* ctx,
                            grpc::ServerReader<v1::CreateTargetRequest>* reader,
                            v1::Target* response) override {
    RpcScope scope(c_, "CreateTarget");
    return scope.Finish(CreateTargetHandler(c_, ctx, reader, &scope).Run(response));
  }

  grpc::Status GetTarget(grpc::ServerContext* ctx, const v1::GetTargetRequest* request,
                         v1::Target* response) override {
    RpcScope scope(c_, "GetTarget");
    return scope.Finish([&]() -> absl::Status {
      if (absl::Status s = c_.auth.Check(*ctx, Access::kUser); !s.ok()) return s;
      if (absl::Status s = ValidateTargetId(request->target_id(), "target_id"); !s.ok()) return s;
      scope.set_target_id(request->target_id());
      auto info = c_.cache.Info(request->target_id());
      if (!info.ok()) return info.status();
      ToProto(*info, response);
      return absl::OkStatus();
    }());
  }

  grpc::Status ListTargets(grpc::ServerContext* ctx, const v1::ListTargetsRequest* request,
                           v1::ListTargetsResponse* response) override {
    RpcScope scope(c_, "ListTargets");
    return scope.Finish([&]() -> absl::Status {
      if (absl::Status s = c_.auth.Check(*ctx, Access::kUser); !s.ok()) return s;
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
        ToProto(info, response->add_targets());
      }
      if (more && response->targets_size() > 0) {
        response->set_next_page_token(response->targets(response->targets_size() - 1).target_id());
      }
      return absl::OkStatus();
    }());
  }

  grpc::Status DeleteTarget(grpc::ServerContext* ctx, const v1::DeleteTargetRequest* request,
                            v1::DeleteTargetResponse*) override {
    RpcScope scope(c_, "DeleteTarget");
    return scope.Finish([&]() -> absl::Status {
      if (absl::Status s = c_.auth.Check(*ctx, Access::kAdmin); !s.ok()) return s;
      if (absl::Status s = ValidateTargetId(request->target_id(), "target_id"); !s.ok()) return s;
      scope.set_target_id(request->target_id());
      return c_.cache.Erase(request->target_id());
    }());
  }

 private:
  ServiceContext& c_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewTargetService(ServiceContext& context) {
  return std::make_unique<TargetServiceImpl>(context);
}

}  // namespace mlsreg::server
