// RegistrationService.AlignScans on gRPC's callback API (the handler; the work is an AlignJob).
#pragma once

#include "grpcpp/grpcpp.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "server/service_context.h"

namespace mlsreg::server {

// At most this many scans in one call.
inline constexpr int kMaxAlignScans = 100;

using AlignScansReactor = grpc::ServerBidiReactor<v1::AlignScansRequest, v1::AlignScansResponse>;

// Starts one call; the reactor belongs to gRPC until OnDone.
AlignScansReactor* StartAlignScans(ServiceContext& c, grpc::CallbackServerContext* ctx);

}  // namespace mlsreg::server
