// AlignScans: many scans into one frame. Pairwise registrations (any method; `auto` by default)
// give relative poses with their pose covariances and overlap information matrices, and a pose
// graph (pose_graph.h) turns them into one pose per scan: edges that disagree with the rest are
// dropped (by the overlap's disagreement, units of d), the kept ones weighed by their covariance.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/enum_names.h"
#include "mlsreg/core/length.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/multiview/merged_cloud.h"
#include "mlsreg/multiview/pose_graph.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg {

// Which pairs of scans are registered.
enum class PairPolicy {
  kSequential,  // (0,1), (1,2), ..., (n-2,n-1)
  kLoop,        // sequential plus (n-1,0): a turntable's closed circle
  kOverlap,     // every pair whose estimated overlap under the initial poses is large enough
};
std::string_view PairPolicyName(PairPolicy policy);  // "sequential", "loop", "overlap"
const EnumNames& PairPolicyNames();

struct AlignOptions {
  // Pose i maps scan i into the common frame. Empty: all identity (the scans are roughly in one
  // frame already, e.g. from a turntable's angles or a robot's odometry applied upstream).
  std::vector<Matrix4> initial_poses;
  PairPolicy pairs = PairPolicy::kLoop;
  // Every policy: an edge whose registration does not verify is not trusted (left out of the
  // pose graph unless it is needed).
  // kOverlap: a pair is registered when at least `min_overlap` of one scan's samples lie within
  // `overlap_distance` of the other scan under the initial poses. Generous, as the poses are
  // rough: a 10 degree error moves the rim of a scan 230 d across by 20 d. In units of the
  // scans' mean d (in (0, 1000]), or in the clouds' units (> 0; e.g. 5 m for a street whose d
  // near the sensor is 2 cm).
  double min_overlap = 0.3;
  GivenLength overlap_distance{20.0, false};
  // Every edge's registration, by default method auto (verified; global when its start fails).
  RegistrationOptions edge;
  // kLoop: a loop closure beyond either bound is reported (AlignResult::loop_closure_exceeded).
  double max_loop_closure_deg = 2.0;
  double max_loop_closure_d = 10.0;
  int anchor = 0;  // the scan whose frame the result is in
  PoseGraphOptions graph;
  int threads = 1;  // edges (and target builds) registered at once
};

struct AlignEdge {
  int from = 0, to = 0;  // the registration of scan `to` (source) onto scan `from` (target)
  Matrix4 relative = Matrix4::Identity();  // maps `to` into `from`'s frame
  RegistrationResult registration;
  VerificationScore verification;  // of the edge's result (registration/verification.h)
  double overlap = 0.0;            // share of `to`'s samples on `from`'s surface after registration
  int correspondences = 0;         // behind the information matrix
  Matrix6 information = Matrix6::Zero();
  double residual_before_d = 0.0, residual_after_d = 0.0;  // pose_graph.h
  bool trusted = true;                                     // its registration verified
  bool kept = true;                                        // used by the final solve
};

struct AlignResult {
  std::vector<Matrix4> poses;          // each scan into the anchor's frame
  std::vector<Matrix4> chained_poses;  // composed along a spanning tree of the edges, unoptimised
  // Per scan: its pose's covariance from the covariance-weighted final solve
  // (PoseGraphResult::pose_covariances): rotation vector, then translation of the scan's origin,
  // in the anchor's frame. Empty for the anchor and when none could be computed.
  std::vector<std::optional<Matrix6>> pose_covariances;
  std::vector<AlignEdge> edges;
  // Per scan: RMS distance between its points under the chained pose and the optimised one
  // (units of d): the drift the graph removed.
  std::vector<double> chain_deviation_d;
  // kLoop: the composition of the loop's edges should be the identity; its rotation (degrees) and
  // the RMS displacement of scan 0's points under it (units of d). Zero otherwise.
  double loop_closure_rotation_deg = 0.0;
  double loop_closure_error_d = 0.0;
  // kLoop: the closure exceeds AlignOptions::max_loop_closure_deg or max_loop_closure_d: some
  // edge is wrong, whatever the graph made of it.
  bool loop_closure_exceeded = false;
  // Scans joined to the anchor by no chain of verified edges: their poses rest on registrations
  // that did not verify and must not be trusted (indices, ascending).
  std::vector<int> unverified_scans;
  double sampling_distance = 0.0;  // the unit d: the mean of the scans' sampling distances
  int graph_iterations = 0;
  // Kept edges the final solve weighed by their pose covariance (PoseGraphOptions).
  int covariance_weighted_edges = 0;
  double seconds = 0.0;
};

struct AlignCallbacks {
  // After each edge's registration (from several threads, one call at a time).
  std::function<void(const AlignEdge& edge, int done, int total)> on_edge;
  StopCheck should_stop;
};

// The checks of AlignScans that need only the scan count (the first four below and the
// options'), e.g. for a server to refuse a request before its data is sent.
absl::Status ValidateAlignOptions(int scan_count, const AlignOptions& options);

// InvalidArgument naming the field for: fewer than 2 scans, a scan that cannot be a target, a
// pose count that is not the scan count, a non-rigid pose, an anchor out of range, a pair graph
// that does not join every scan. CANCELLED when stopped.
absl::StatusOr<AlignResult> AlignScans(const std::vector<PointCloud>& scans,
                                       const AlignOptions& options,
                                       const AlignCallbacks& callbacks = {});

// The same over scans already built as targets (e.g. a server's cached ones); each target's
// cloud is the scan. Targets built with features give the overlaps their oriented samples.
absl::StatusOr<AlignResult> AlignTargets(const std::vector<std::shared_ptr<const Target>>& targets,
                                         const AlignOptions& options,
                                         const AlignCallbacks& callbacks = {});

}  // namespace mlsreg
