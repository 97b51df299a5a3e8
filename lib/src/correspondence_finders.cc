#include "mlsreg/correspondence_finders.h"

namespace mlsreg {

void ClosestPointFinder::Find(std::span<const Vec3> queries, std::span<Correspondence> out) {
  const SurfaceProperties& surface = target_.surface();
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Neighbor nn = target_.tree().Nearest(queries[i]);
    Correspondence& c = out[i];
    c.point = target_.points()[nn.index];
    c.normal = surface.normals[nn.index];
    c.curvature = surface.curvature[nn.index];
    c.valid = surface.valid[nn.index] != 0;
  }
}

MlsCorrespondenceFinder::MlsCorrespondenceFinder(const Target& target, const MlsOptions& options,
                                                 bool warm_start, FarQueryPolicy far_queries)
    : projector_(target.points(), target.tree(), options,
                 target.surface().oriented ? &target.surface().normals : nullptr),
      warm_start_(warm_start),
      far_queries_(far_queries),
      oriented_(target.surface().oriented),
      radius_(options.radius) {
  projector_.set_seed_far_queries_from_nearest_sample(far_queries != FarQueryPolicy::kDrop);
}

void MlsCorrespondenceFinder::Refine() {
  far_queries_ = FarQueryPolicy::kDrop;
  projector_.set_seed_far_queries_from_nearest_sample(false);
}

void MlsCorrespondenceFinder::Find(std::span<const Vec3> queries, std::span<Correspondence> out) {
  if (previous_.size() != queries.size()) {
    previous_.assign(queries.size(), MlsProjection{});
    status_.assign(queries.size(), ProjectionStatus::kTooFewNeighbors);
  }
  last_iterations_ = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const Vec3& q = queries[i];
    MlsProjection& previous = previous_[i];
    MlsProjection projection;
    // Warm start only from a direct projection that is still within the support of the query;
    // otherwise (first iteration, far or boundary queries) run Algorithm 1 from the query.
    if (warm_start_ && previous.status == ProjectionStatus::kOk &&
        !previous.seeded_from_nearest_sample &&
        (q - previous.point).squaredNorm() < radius_ * radius_) {
      const Vec3 start = q - (q - previous.point).dot(previous.normal) * previous.normal;
      projection = projector_.ProjectFrom(start, workspace_);
    } else {
      projection = projector_.Project(q, workspace_);
    }
    last_iterations_ += projection.iterations;
    Correspondence& c = out[i];
    c.point = projection.point;
    c.normal = projection.normal;
    c.curvature = projection.curvature;
    c.valid = projection.status == ProjectionStatus::kOk;
    status_[i] = projection.status;
    previous = projection;
  }
}

}  // namespace mlsreg
