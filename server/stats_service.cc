// StatsService.GetStats: request counts, latencies, pool and cache state.
#include <chrono>

#include "grpcpp/grpcpp.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "server/rpc_scope.h"
#include "server/services.h"

namespace mlsreg::server {
namespace {

class StatsServiceImpl final : public v1::StatsService::Service {
 public:
  explicit StatsServiceImpl(ServiceContext& c) : c_(c) {}

  grpc::Status GetStats(grpc::ServerContext* ctx, const v1::GetStatsRequest*,
                        v1::GetStatsResponse* response) override {
    RpcScope scope(c_, "GetStats", ctx, kReadRpc);
    if (!scope.admission().ok()) return scope.Finish(scope.admission());
    c_.stats.Fill(response);
    response->set_workers(c_.jobs.workers());
    response->set_active_jobs(c_.jobs.active());
    response->set_queue_depth(c_.jobs.queued());
    response->set_queue_capacity(c_.jobs.queue_capacity());
    const CacheCounters cache = c_.cache.counters();
    response->set_cache_bytes(cache.bytes);
    response->set_cache_budget_bytes(cache.budget_bytes);
    response->set_cache_entries(cache.entries);
    response->set_cache_hits(cache.hits);
    response->set_cache_misses(cache.misses);
    response->set_cache_evictions(cache.evictions);
    response->set_uptime_seconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - c_.started).count());
    response->set_serving(c_.state.accepting());
    response->set_inflight_bytes(c_.inflight.used());
    response->set_inflight_budget_bytes(c_.inflight.budget());
    response->set_open_streams(c_.streams.open_streams());
    return scope.Finish(absl::OkStatus());
  }

 private:
  ServiceContext& c_;
};

}  // namespace

std::unique_ptr<grpc::Service> NewStatsService(ServiceContext& context) {
  return std::make_unique<StatsServiceImpl>(context);
}

}  // namespace mlsreg::server
