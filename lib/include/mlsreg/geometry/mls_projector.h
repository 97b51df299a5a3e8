// MlsProjector: projects points onto the moving-least-squares surface of a target point set,
// exactly as the paper's Algorithm 1 (Dutta, Russig, Gumhold 2019, section 4).
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "mlsreg/core/parallel_for.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/height_field_fit.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/weighted_covariance.h"

namespace mlsreg {

struct MlsOptions {
  // Support radius r of the Wendland weight, in the target's units (not in d: callers convert).
  double radius = 0.0;
  // Degree g of the bivariate height-field polynomial (paper Table 2: 3).
  int polynomial_degree = 3;
  // Iteration cap of Algorithm 1 (paper Table 2: 20).
  int max_iterations = 20;
  // Converged when one iteration moves the point by less than this (absolute). 0: 1e-3 * radius.
  double tolerance = 0.0;
  // Neighbours are gathered within radius * (1 + search_margin) and reused while the iterate
  // stays within radius * search_margin of where they were gathered (same result, fewer searches).
  double search_margin = 0.0;
  // A query with fewer than 3 target samples within r cannot start Algorithm 1. When true, the
  // iteration starts from the nearest target sample instead (an MLS-smoothed closest point);
  // when false such queries fail with kTooFewNeighbors.
  bool seed_far_queries_from_nearest_sample = true;
};

enum class ProjectionStatus : std::uint8_t {
  kOk = 0,
  kTooFewNeighbors,  // fewer than 3 weighted samples within r of the iterate
  kDegenerate,       // the neighbourhood is a line or a point; no reference plane exists
  kNotConverged,     // still moving after max_iterations
  kLineSupport,      // ProjectUnlessLine: the first fit's support lies along a line
};
std::string_view ProjectionStatusName(ProjectionStatus status);

struct MlsProjection {
  Vec3 point = Vec3::Zero();
  // Surface normal from the gradient of the fitted polynomial, unit length. It points toward the
  // projector's viewpoint when it has one, and its sign is arbitrary otherwise.
  Vec3 normal = Vec3::UnitZ();
  // Surface variation H of the weighted PCA at the final iterate (paper Eq. 8).
  double curvature = 0.0;
  ProjectionStatus status = ProjectionStatus::kTooFewNeighbors;
  int iterations = 0;
  int neighbors = 0;  // samples with non-zero weight in the last fit
  // True when the query was too far from the target and the iteration started from its nearest
  // sample (MlsOptions::seed_far_queries_from_nearest_sample).
  bool seeded_from_nearest_sample = false;
  // MLS patches of a scan: a blended patch's support lies on one scan line (MlsPatches).
  bool one_scan_line = false;
};

// One step of Algorithm 1 at an iterate s (lines 4-9): the Wendland-weighted reference plane
// around s and the height field fitted over it.
struct MlsLocalFit {
  LocalFrame frame;            // weighted PCA around s, toward the viewpoint when known
  Vec3 origin = Vec3::Zero();  // s projected onto the reference plane: the height field's origin
  // g over ((p - origin) . u, (p - origin) . v) / r, heights in units of r.
  HeightField height;
};

// Target samples gathered once around a point and kept for later projections nearby: every
// sample within `reach` of `center` is listed (in search order). An ICP loop's fine phase moves
// each query by a small fraction of the support radius per iteration, so a query keeping its
// neighbourhood, gathered a little wider than the support, finds its support there for many
// iterations instead of searching the tree each time. The projection is the same either way:
// samples beyond the support weigh nothing.
struct KeptNeighborhood {
  Vec3 center = Vec3::Zero();
  double reach = -1.0;  // negative: empty
  RadiusNeighbors samples;
};

class MlsProjector {
 public:
  // How much wider than the support radius a kept neighbourhood is gathered (a fraction of r).
  static constexpr double kKeptMargin = 0.1;

  // Scratch buffers for one thread. Reusing one keeps projections allocation-free.
  struct Workspace {
    KeptNeighborhood gathered;  // a projection's own neighbourhood, when it keeps none
    std::vector<double> weights;
    // The fit of the last projection's final iteration (valid when its status is kOk): the
    // local surface at the projected point.
    MlsLocalFit last_fit;
  };

  // `points` and `tree` must outlive the projector. With a `viewpoint` (where the target was
  // scanned from), output normals point toward it; without, their sign is arbitrary.
  MlsProjector(const std::vector<Vec3>& points, const KdTree& tree, const MlsOptions& options,
               const std::optional<Vec3>& viewpoint = std::nullopt);

  // Algorithm 1 started at the query itself (s <- p).
  MlsProjection Project(const Vec3& query, Workspace& workspace) const;

  // Algorithm 1 started at `start` instead of the query (warm start). A good start is the query
  // projected onto the tangent plane of its previous projection: it keeps the query's tangential
  // position while skipping the iterations that walk onto the surface.
  // With `kept`, the iterate's support comes from that neighbourhood while it covers it, and the
  // neighbourhood is gathered again (kKeptMargin wider than the support) where it does not.
  MlsProjection ProjectFrom(const Vec3& start, Workspace& workspace,
                            KeptNeighborhood* kept = nullptr) const;

  // Algorithm 1 started at the query, giving up after the first iteration's weighted PCA when
  // its support lies along a line: the middle principal spread (eigenvalue) below `min_spread`
  // of the largest (kLineSupport; no height field is fitted). Otherwise exactly Project. A scan's
  // far rings make such supports (MlsPatches grows them), and the iterations that would walk
  // onto a line's surface only to find it a line are spared.
  MlsProjection ProjectUnlessLine(const Vec3& query, Workspace& workspace, double min_spread) const;

  const MlsOptions& options() const { return options_; }
  void set_seed_far_queries_from_nearest_sample(bool seed) {
    options_.seed_far_queries_from_nearest_sample = seed;
  }

 private:
  // Lines 4-9 at the iterate `s` over the gathered `candidates`, into `workspace.last_fit`; kOk,
  // kTooFewNeighbors (< 3 weighted samples) or kDegenerate.
  // With `min_spread` > 0, kLineSupport when the PCA's middle spread is below it (relative to
  // the largest), before the height field.
  ProjectionStatus Fit(const Vec3& s, const RadiusNeighbors& candidates, Workspace& workspace,
                       int& neighbors, double min_spread = 0.0) const;
  MlsProjection Iterate(const Vec3& start, Workspace& workspace, KeptNeighborhood* kept,
                        double first_min_spread) const;

  const std::vector<Vec3>& points_;
  const KdTree& tree_;
  std::optional<Vec3> viewpoint_;
  MlsOptions options_;
};

// Projects the points point_of(0), ..., point_of(count - 1) by `projector`, split over `threads`,
// and hands each result to visit(i, projection, workspace) (the workspace holds the projection's
// final fit). Asks `should_stop` every 64 points; false when it said stop.
template <class PointOf, class Visit>
bool ProjectEach(const MlsProjector& projector, std::size_t count, const PointOf& point_of,
                 const Visit& visit, int threads, const StopCheck& should_stop) {
  return ParallelForUntilStopped<MlsProjector::Workspace>(
      count, threads, should_stop,
      [&](std::size_t i, MlsProjector::Workspace& workspace) {
        visit(i, projector.Project(point_of(i), workspace), workspace);
      },
      64);
}

}  // namespace mlsreg
