#include "mlsreg/geometry/mls_projector.h"

#include <algorithm>
#include <cmath>

#include "mlsreg/geometry/wendland.h"

namespace mlsreg {

std::string_view ProjectionStatusName(ProjectionStatus status) {
  switch (status) {
    case ProjectionStatus::kOk:
      return "ok";
    case ProjectionStatus::kTooFewNeighbors:
      return "too_few_neighbors";
    case ProjectionStatus::kDegenerate:
      return "degenerate";
    case ProjectionStatus::kNotConverged:
      return "not_converged";
    case ProjectionStatus::kLineSupport:
      return "line_support";
  }
  return "unknown";
}

MlsProjector::MlsProjector(const std::vector<Vec3>& points, const KdTree& tree,
                           const MlsOptions& options, const std::optional<Vec3>& viewpoint)
    : points_(points), tree_(tree), viewpoint_(viewpoint), options_(options) {
  if (options_.tolerance <= 0.0) options_.tolerance = 1e-3 * options_.radius;
}

MlsProjection MlsProjector::Project(const Vec3& query, Workspace& workspace) const {
  return ProjectFrom(query, workspace);
}

ProjectionStatus MlsProjector::Fit(const Vec3& s, const RadiusNeighbors& candidates, Workspace& ws,
                                   int& neighbors, double min_spread) const {
  const double r = options_.radius;
  // Lines 4-7: Wendland weights around s, weighted mean and weighted PCA.
  const std::size_t n = candidates.size();
  if (ws.weights.size() < n) ws.weights.resize(n);
  const double r_squared = r * r;
  WeightedCovariance covariance(s);
  for (std::size_t j = 0; j < n; ++j) {
    const Vec3& q = points_[candidates[j].first];
    const double distance_squared = (q - s).squaredNorm();
    // Outside the support (a kept neighbourhood's margin): no square root needed.
    const double w =
        distance_squared < r_squared ? WendlandWeight(std::sqrt(distance_squared), r) : 0.0;
    ws.weights[j] = w;
    if (w <= 0.0) continue;
    covariance.Add(q, w);
  }
  neighbors = covariance.count();
  if (covariance.count() < 3) return ProjectionStatus::kTooFewNeighbors;
  MlsLocalFit& fit = ws.last_fit;
  LocalFrame& frame = fit.frame;
  if (!covariance.Finalize(frame)) return ProjectionStatus::kDegenerate;
  if (min_spread > 0.0 && frame.eigenvalues[1] < min_spread * frame.eigenvalues[2]) {
    return ProjectionStatus::kLineSupport;
  }
  if (viewpoint_ && frame.normal.dot(*viewpoint_ - frame.mean) < 0.0) {
    frame.normal = -frame.normal;
    frame.tangent_v = -frame.tangent_v;  // keep (u, v, n) right-handed
  }

  // Line 8: project the iterate onto the reference plane.
  fit.origin = s - (s - frame.mean).dot(frame.normal) * frame.normal;

  // Line 9: fit the height field over the plane, in coordinates scaled by 1/r.
  HeightFieldFit height_fit(options_.polynomial_degree);
  const double inv_r = 1.0 / r;
  for (std::size_t j = 0; j < n; ++j) {
    if (ws.weights[j] <= 0.0) continue;
    const Vec3 local = (points_[candidates[j].first] - fit.origin) * inv_r;
    height_fit.Add(local.dot(frame.tangent_u), local.dot(frame.tangent_v), local.dot(frame.normal),
                   ws.weights[j]);
  }
  if (!height_fit.Finalize(fit.height)) return ProjectionStatus::kDegenerate;
  return ProjectionStatus::kOk;
}

MlsProjection MlsProjector::ProjectUnlessLine(const Vec3& query, Workspace& workspace,
                                              double min_spread) const {
  return Iterate(query, workspace, nullptr, min_spread);
}

MlsProjection MlsProjector::ProjectFrom(const Vec3& start, Workspace& workspace,
                                        KeptNeighborhood* kept) const {
  return Iterate(start, workspace, kept, 0.0);
}

MlsProjection MlsProjector::Iterate(const Vec3& start, Workspace& ws, KeptNeighborhood* kept,
                                    double first_min_spread) const {
  const double r = options_.radius;
  const double margin =
      kept ? std::max(options_.search_margin, kKeptMargin) : options_.search_margin;
  const double gather_radius = r * (1.0 + margin);
  // Where the candidates live, and whether they cover the support of an iterate.
  KeptNeighborhood& gathered = kept ? *kept : ws.gathered;
  if (!kept) gathered.reach = -1.0;
  const auto covers = [&](const Vec3& s) {
    return gathered.reach >= 0.0 && (s - gathered.center).norm() + r <= gathered.reach;
  };
  const auto gather = [&](const Vec3& s) {
    tree_.Radius(s, gather_radius, gathered.samples);
    gathered.center = s;
    // A search that hit its cap holds only the nearest samples: no reach to rely on.
    gathered.reach = gathered.samples.size() < kMaxRadiusNeighbors ? gather_radius : r;
  };

  MlsProjection result;
  Vec3 s = start;  // the iterate of Algorithm 1
  bool reseeded = false;

  for (int iteration = 1; iteration <= options_.max_iterations; ++iteration) {
    result.iterations = iteration;
    if (!covers(s)) gather(s);
    const ProjectionStatus status =
        Fit(s, gathered.samples, ws, result.neighbors, iteration == 1 ? first_min_spread : 0.0);
    if (status == ProjectionStatus::kTooFewNeighbors && iteration == 1 && !reseeded &&
        options_.seed_far_queries_from_nearest_sample && tree_.size() > 0) {
      // The query is too far from the target to start Algorithm 1: start from the closest
      // target sample. This costs one iteration of the budget.
      s = points_[tree_.Nearest(s).index];
      gathered.reach = -1.0;
      reseeded = true;
      result.seeded_from_nearest_sample = true;
      continue;
    }
    if (status != ProjectionStatus::kOk) {
      result.status = status;
      return result;
    }

    // Line 10: move onto the polynomial surface.
    const MlsLocalFit& fit = ws.last_fit;
    const Vec3 next = fit.origin + (fit.height.ValueAtOrigin() * r) * fit.frame.normal;
    const double move = (next - s).norm();
    s = next;
    result.point = s;
    result.normal = (fit.frame.normal - fit.height.SlopeX() * fit.frame.tangent_u -
                     fit.height.SlopeY() * fit.frame.tangent_v)
                        .normalized();
    result.curvature = fit.frame.surface_variation;
    if (move < options_.tolerance) {
      result.status = ProjectionStatus::kOk;
      return result;
    }
  }
  result.status = ProjectionStatus::kNotConverged;
  return result;
}

}  // namespace mlsreg
