// The three mlsreg.v1 services, as grpc::Service objects to register with a ServerBuilder.
// Handlers are thin: they authenticate, validate and translate, and leave the CPU work to the
// JobPool (builds, registrations) so that gRPC threads only wait.
#pragma once

#include <memory>

#include "server/service_context.h"

namespace grpc {
class Service;
}

namespace mlsreg::server {

// CreateTarget, GetTarget, ListTargets, DeleteTarget.
std::unique_ptr<grpc::Service> NewTargetService(ServiceContext& context);
// Register (bidi stream: header + source chunks in; Accepted, Progress..., Result out) and
// AlignScans (header + uploaded scans' chunks in; Accepted, AlignProgress per edge, result out).
std::unique_ptr<grpc::Service> NewRegistrationService(ServiceContext& context);
// GetStats.
std::unique_ptr<grpc::Service> NewStatsService(ServiceContext& context);

}  // namespace mlsreg::server
