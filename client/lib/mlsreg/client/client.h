// mlsreg::client::Client: the C++ API of remote mlsreg servers, in domain types. It hides
// chunking, applies default deadlines, retries transient failures (UNAVAILABLE, and
// RESOURCE_EXHAUSTED unless the server said it is final: trailing metadata
// mlsreg-retry-after-ms = -1) with exponential backoff and jitter, waiting at least as long as the
// server asked, and reuses one channel per server.
//
// With several servers (replicas), every call about a target goes to the replica chosen by
// rendezvous hashing of the target id, so each replica caches only its share of the targets.
// When that replica is down the call moves to the next one in the target's order; when a replica
// answers NOT_FOUND for a target this client uploaded, the client uploads it again and retries.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/target_info.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/registration/registration.h"

namespace mlsreg::client {

struct ClientOptions {
  // One server "host:port", several separated by commas (replicas), or "dns:///NAME:PORT",
  // which is resolved to every address behind the name (e.g. a Kubernetes headless service).
  std::string address = "127.0.0.1:50051";
  // TLS: set `tls` (server verified against `ca_cert`, or the system roots when empty); mutual
  // TLS when client_cert and client_key are given. All are PEM file paths.
  bool tls = false;
  std::string ca_cert, client_cert, client_key;
  std::string token;                // sent as "authorization: Bearer <token>" when not empty
  double deadline_seconds = 600.0;  // per call
  int max_attempts = 5;             // per call, for transient failures
  double initial_backoff_seconds = 0.2;
  double max_backoff_seconds = 5.0;
  std::size_t chunk_bytes = 1 << 20;  // upload chunk size (the server accepts <= 4 MiB)
  bool float32 = false;               // send coordinates as float32 (half the bytes, rounded)
};

struct RemoteRegistrationResult {
  std::string request_id;
  RegistrationResult result;  // trace holds the progress messages received
  std::optional<PoseError> ground_truth_error;
  double queue_seconds = 0.0;
  int attempts = 1;
};

// One scan of a remote AlignScans: a target already on the server, or a cloud sent with the call.
struct RemoteScan {
  std::string target_id;                    // set: a target on the server
  std::shared_ptr<const PointCloud> cloud;  // else: uploaded in the call (not kept there)
};

struct RemoteAlignResult {
  std::string request_id;
  AlignResult result;  // an edge's trace holds only its last iteration
  double queue_seconds = 0.0;
  int attempts = 1;
};

struct ServerHealth {
  bool serving = false;
  std::string status;  // SERVING, NOT_SERVING, ...
};

// The interface; Connect makes the gRPC implementation. Its methods are virtual so that a
// program can reach a client through a transport module it loads only when it needs one (the
// mlsreg tool: cli/transport.h), without linking gRPC itself.
class Client {
 public:
  static absl::StatusOr<std::unique_ptr<Client>> Connect(const ClientOptions& options);
  virtual ~Client() = default;

  // Uploads to the target's replica, declaring the cloud's digest: when the replica already
  // holds the same content under `id` it answers at once (no data is sent); other content under
  // `id` is ALREADY_EXISTS. The client keeps a reference to the cloud so it can upload it again if
  // a replica loses it (restart without storage, or re-routing).
  virtual absl::StatusOr<TargetInfo> UploadTarget(const std::string& id,
                                                  std::shared_ptr<const PointCloud> cloud) = 0;
  absl::StatusOr<TargetInfo> UploadTarget(const std::string& id, const PointCloud& cloud) {
    return UploadTarget(id, std::make_shared<const PointCloud>(cloud));
  }
  virtual absl::StatusOr<TargetInfo> GetTarget(const std::string& id) = 0;
  // The digest the server will compute for `cloud` as this client sends it (float32 rounding
  // included).
  virtual std::string DigestAsSent(const PointCloud& cloud) const = 0;
  // All pages of every replica.
  virtual absl::StatusOr<std::vector<TargetInfo>> ListTargets() = 0;
  virtual absl::Status DeleteTarget(const std::string& id) = 0;

  // Streams a registration; `on_progress` (may be empty) sees every progress message. Set
  // `*cancel` (may be null) to true from another thread to cancel the call.
  virtual absl::StatusOr<RemoteRegistrationResult> Register(
      const std::string& target_id, const PointCloud& source, const Matrix4& initial,
      const RegistrationOptions& options, const std::optional<Matrix4>& ground_truth = {},
      const std::function<void(const IterationReport&)>& on_progress = {},
      const std::atomic<bool>* cancel = nullptr) = 0;

  // Aligns many scans into one frame on one server: the replica of the first cached scan's
  // target id (every cached scan must be on it), or any replica when all are uploaded.
  // `on_edge` (may be empty) sees every edge as it finishes, with the count done and the total;
  // once each, also when a transient failure made the call run again.
  // Set `*cancel` (may be null) to true from another thread to cancel the call.
  virtual absl::StatusOr<RemoteAlignResult> AlignScans(
      const std::vector<RemoteScan>& scans, const AlignOptions& options,
      const std::function<void(const AlignEdge&, int done, int total)>& on_edge = {},
      const std::atomic<bool>* cancel = nullptr) = 0;

  // The overall health of replica `replica` ("" service), via grpc.health.v1.
  virtual absl::StatusOr<ServerHealth> Health(std::size_t replica = 0) = 0;
  // Replica `replica`'s statistics as JSON text (the GetStats response).
  virtual absl::StatusOr<std::string> StatsJson(std::size_t replica = 0) = 0;

  // The replicas, in the order given (or resolved), and the one a target id maps to first.
  virtual std::vector<std::string> replicas() const = 0;
  virtual std::string ReplicaFor(const std::string& target_id) const = 0;

  const ClientOptions& options() const { return options_; }

 protected:
  explicit Client(const ClientOptions& options) : options_(options) {}

 private:
  ClientOptions options_;
};

}  // namespace mlsreg::client
