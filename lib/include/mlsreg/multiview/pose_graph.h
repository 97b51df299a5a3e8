// A pose graph over SE(3): N poses (each mapping its scan into the common frame) tied by relative
// measurements with information matrices, solved by Ceres (Levenberg-Marquardt, quaternion
// manifold) with a robust loss, then edges that still disagree dropped and the rest solved again.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/transform.h"

namespace mlsreg {

using Matrix6 = Eigen::Matrix<double, 6, 6>;

// Edge (from, to): `measurement` maps the points of scan `to` into the frame of scan `from`, i.e.
// it estimates inverse(pose[from]) * pose[to]. `information` weighs the twist [rotation (rad);
// translation] of the disagreement, applied on the left in `from`'s frame, so that
// xi^T information xi is a squared length in units of d (see EdgeInformation).
struct PoseGraphEdge {
  int from = 0, to = 0;
  Matrix4 measurement = Matrix4::Identity();
  Matrix6 information = Matrix6::Identity();
  // The measurement's covariance, in the twist's coordinates (a registration's pose_covariance:
  // registration/verification.h), when it has one. The final solve weighs the kept edges by its
  // inverse (PoseGraphOptions::weigh_by_covariance); `information` still measures disagreement.
  std::optional<Matrix6> covariance = std::nullopt;
  // An untrusted edge (e.g. a registration that did not verify) is left out from the start,
  // unless the graph would fall apart without it.
  bool trusted = true;
};

struct PoseGraphOptions {
  int anchor = 0;               // its pose is held fixed
  double robust_scale_d = 1.0;  // Cauchy loss scale: disagreement (units of d) where it bends
  double reject_above_d = 2.0;  // after the robust solve, edges disagreeing more are dropped
  int max_iterations = 100;
  // The final solve, over the kept edges only, weighs each by its covariance's inverse: edges
  // certain in a direction (two façades) pull the poses more along it than edges the data barely
  // fix there (a bare road). A kept edge without a covariance gets its `information` scaled by the
  // kept edges' median ratio of the two (EdgeWeights). Off, or with no kept edge carrying a
  // covariance: `information`, as the robust solve.
  bool weigh_by_covariance = true;
  // The reported pose covariances count what edges that share a scan share. Each edge's error
  // comes about half from each scan's data, so two edges sharing a scan correlate by about 1/2,
  // and k such edges carry 1 + (k - 1) / 2 times less information than k independent ones. Each
  // kept edge's covariance is inflated by 1 + shared_scan_noise * (kept edges sharing one of its
  // scans), with 1/4: the correlation 1/2, averaged over the edge's two scans. 0: the final solve's
  // own covariance, which takes the edges as independent and comes out 1.4-4.5 times too small
  // in sigma on the synthetic street sequences (docs/scenes.md). The poses do not depend on it.
  double shared_scan_noise = 0.25;
};

struct PoseGraphResult {
  std::vector<Matrix4> poses;
  // Per edge: its disagreement sqrt(xi^T information xi) (units of d) at the initial poses and
  // at the result, and whether it was kept for the final solve.
  std::vector<double> residual_before_d, residual_after_d;
  std::vector<bool> kept;
  // Kept edges the final solve weighed by their covariance (0: none, by `information`).
  int covariance_weighted = 0;
  // Per pose, when covariance_weighted > 0: the covariance of the small motion (rotation vector
  // in radians, then translation of the pose's origin) that would take it to the truth, in the
  // anchor's frame: R_truth = exp(w) R, t_truth = t + v. As calibrated as the edges'
  // covariances, with the noise edges share through their scans counted (shared_scan_noise). Empty
  // for the anchor, and when the kept edges leave some direction of some pose unconstrained.
  std::vector<std::optional<Matrix6>> pose_covariances;
  int iterations = 0;  // of both solves
};

// The 1-sigma extent of a pose covariance (rotation vector, translation) along its least certain
// rotation (degrees) and translation (the clouds' units).
struct PoseSigmas {
  double rotation_deg = 0.0, translation = 0.0;
};
PoseSigmas SigmasOf(const Matrix6& covariance);

// The disagreement of an edge at the given poses (units of d).
double EdgeResidual(const PoseGraphEdge& edge, const std::vector<Matrix4>& poses);

// Starts from `initial` (one pose per node). Untrusted edges are left out, then edges that still
// disagree after the robust solve are dropped, worst first; an edge is only ever left out while
// the graph stays connected without it. InvalidArgument for bad indices or sizes.
absl::StatusOr<PoseGraphResult> OptimisePoseGraph(const std::vector<Matrix4>& initial,
                                                  const std::vector<PoseGraphEdge>& edges,
                                                  const PoseGraphOptions& options = {});

// Whether the undirected graph of `edges` (those with kept[e] when given) joins all n nodes;
// `unreachable` lists the nodes not reached from node 0.
bool IsConnected(int n, const std::vector<PoseGraphEdge>& edges, const std::vector<bool>* kept,
                 std::vector<int>* unreachable = nullptr);

}  // namespace mlsreg
