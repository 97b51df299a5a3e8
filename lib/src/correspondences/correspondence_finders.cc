#include "mlsreg/correspondences/correspondence_finders.h"

#include <cmath>

#include "mlsreg/core/parallel_for.h"

namespace mlsreg {

void ClosestPointFinder::Find(std::span<const Vec3> queries, std::span<Correspondence> out) {
  const SurfaceProperties& surface = target_.surface();
  ParallelFor(
      queries.size(), threads_,
      [&](std::size_t begin, std::size_t end, int) {
        for (std::size_t i = begin; i < end; ++i) {
          const Neighbor nn = target_.tree().Nearest(queries[i]);
          Correspondence& c = out[i];
          c.point = target_.points()[nn.index];
          c.normal = surface.normals[nn.index];
          c.curvature = surface.curvature[nn.index];
          c.valid = surface.valid[nn.index] != 0;
        }
      },
      512);
}

namespace {

// Whether patches were built for these projection options.
bool PatchesFit(const MlsPatches& patches, const MlsOptions& options) {
  return std::abs(patches.radius() - options.radius) <= 1e-9 * options.radius &&
         patches.polynomial_degree() == options.polynomial_degree &&
         patches.mls_options().max_iterations == options.max_iterations;
}

}  // namespace

MlsCorrespondenceFinder::MlsCorrespondenceFinder(const Target& target, const MlsOptions& options,
                                                 bool warm_start, FarQueryPolicy far_queries,
                                                 MlsProjectionKind projection)
    : target_(target),
      projector_(target.points(), target.tree(), options, target.cloud().viewpoint),
      warm_start_(warm_start),
      far_queries_(far_queries),
      projection_(projection),
      oriented_(target.oriented()),
      radius_(options.radius) {
  projector_.set_seed_far_queries_from_nearest_sample(far_queries != FarQueryPolicy::kDrop);
  if (projection_ != MlsProjectionKind::kExact && target.mls_patches() &&
      PatchesFit(*target.mls_patches(), options)) {
    patches_ = target.mls_patches();
  }
}

void MlsCorrespondenceFinder::Refine() {
  far_queries_ = FarQueryPolicy::kDrop;
  projector_.set_seed_far_queries_from_nearest_sample(false);
  if (projection_ == MlsProjectionKind::kPatchesThenExact) {
    // The fine phase projects exactly; warm starts carry over from the patches' projections.
    projection_ = MlsProjectionKind::kExact;
    patches_ = nullptr;
  }
}

namespace {

// Keeps v[kept[0]], v[kept[1]], ... at the front (kept ascending) and drops the rest; a vector
// not yet sized for the queries stays as it is.
template <typename T>
void KeepEntries(std::vector<T>& v, std::span<const std::uint32_t> kept, std::size_t queries) {
  if (v.size() != queries) return;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    if (kept[k] != k) v[k] = std::move(v[kept[k]]);
  }
  v.resize(kept.size());
}

}  // namespace

void MlsCorrespondenceFinder::KeepOnly(std::span<const std::uint32_t> kept) {
  const std::size_t queries = previous_.size();
  KeepEntries(previous_, kept, queries);
  KeepEntries(status_, kept, queries);
  KeepEntries(anchors_, kept, queries);
  KeepEntries(kept_, kept, queries);
}

bool MlsCorrespondenceFinder::EnsurePatches() {
  if (projection_ == MlsProjectionKind::kExact || patches_) return true;
  MlsOptions options = projector_.options();
  options.seed_far_queries_from_nearest_sample = true;
  absl::StatusOr<MlsPatches> built =
      MlsPatches::Build(target_.points(), target_.tree(), options, target_.cloud().viewpoint,
                        PatchFitting::kOnFirstUse, threads_, should_stop_, target_.scan_sensor());
  if (absl::IsCancelled(built.status())) return false;
  if (built.ok()) {
    own_patches_ = *std::move(built);
    patches_ = &*own_patches_;
  } else {
    projection_ = MlsProjectionKind::kExact;  // no patch fits: the exact projection reports why
  }
  return true;
}

void MlsCorrespondenceFinder::Find(std::span<const Vec3> queries, std::span<Correspondence> out) {
  if (!EnsurePatches()) return;
  if (previous_.size() != queries.size()) {
    previous_.assign(queries.size(), MlsProjection{});
    status_.assign(queries.size(), ProjectionStatus::kTooFewNeighbors);
  }
  if (anchors_.size() != queries.size() || anchors_of_ != patches_) {
    anchors_.assign(queries.size(), MlsPatches::AnchorCache{});
    seeds_.assign(queries.size(), MlsPatches::SeedMemo{});
    anchors_of_ = patches_;
  }
  if (!patches_ && kept_.size() != queries.size()) kept_.assign(queries.size(), {});
  last_iterations_ = 0;
  if (threads_state_.size() < static_cast<std::size_t>(threads_)) threads_state_.resize(threads_);
  for (ThreadState& state : threads_state_) state.iterations = 0;
  ParallelFor(
      queries.size(), threads_,
      [&](std::size_t begin, std::size_t end, int worker) {
        FindRange(queries, out, begin, end, threads_state_[worker]);
      },
      16);
  for (const ThreadState& state : threads_state_) last_iterations_ += state.iterations;
}

MlsProjection MlsCorrespondenceFinder::ProjectOne(const Vec3& query, const Vec3* start,
                                                  MlsProjector::Workspace& workspace,
                                                  MlsPatches::AnchorCache& anchors,
                                                  MlsPatches::SeedMemo& seed,
                                                  KeptNeighborhood* kept) const {
  const bool seed_far = far_queries_ != FarQueryPolicy::kDrop;
  if (patches_) {
    return start ? patches_->ProjectNear(query, *start, seed_far, &anchors)
                 : patches_->Project(query, seed_far, &anchors, &seed);
  }
  const MlsProjection projection = projector_.ProjectFrom(start ? *start : query, workspace, kept);
  // A neighbourhood in a dense cluster is not worth its memory for every sample.
  if (kept && kept->samples.capacity() > kMaxKeptSamples) {
    RadiusNeighbors().swap(kept->samples);
    kept->reach = -1.0;
  }
  return projection;
}

bool MlsCorrespondenceFinder::FindRange(std::span<const Vec3> queries,
                                        std::span<Correspondence> out, std::size_t begin,
                                        std::size_t end, ThreadState& state) {
  MlsProjector::Workspace& workspace = state.workspace;
  long iterations = 0;
  // A projection can take thousands of neighbour visits in dense clusters: ask often.
  constexpr std::uint32_t kStopInterval = 64;
  StopPoller stop(should_stop_, kStopInterval);
  for (std::size_t i = begin; i < end; ++i) {
    if (stop.Poll()) {
      state.iterations = iterations;
      return false;
    }
    const Vec3& q = queries[i];
    MlsProjection& previous = previous_[i];
    // Warm start only from a direct projection that is still within the support of the query;
    // otherwise (first iteration, far or boundary queries) start from the query.
    const bool warm = warm_start_ && previous.status == ProjectionStatus::kOk &&
                      !previous.seeded_from_nearest_sample &&
                      (q - previous.point).squaredNorm() < radius_ * radius_;
    const Vec3 start = q - (q - previous.point).dot(previous.normal) * previous.normal;
    // A query still travelling (farther than the kept margin since its last projection) would
    // outrun any neighbourhood it kept: it searches the tree alone until it slows down.
    const bool keeps =
        !patches_ && warm &&
        (start - previous.point).squaredNorm() <
            MlsProjector::kKeptMargin * MlsProjector::kKeptMargin * radius_ * radius_;
    const MlsProjection projection = ProjectOne(q, warm ? &start : nullptr, workspace, anchors_[i],
                                                seeds_[i], keeps ? &kept_[i] : nullptr);
    iterations += projection.iterations;
    Correspondence& c = out[i];
    c.point = projection.point;
    c.normal = projection.normal;
    c.curvature = projection.curvature;
    c.valid = projection.status == ProjectionStatus::kOk;
    status_[i] = projection.status;
    previous = projection;
  }
  state.iterations = iterations;
  return true;
}

void ReverseCalibrationFinder::Find(std::span<const Vec3> queries, std::span<Correspondence> out) {
  const DepthGrid& grid = *target_.grid();
  const std::vector<Vec3>& points = target_.points();
  const SurfaceProperties& surface = target_.surface();
  for (std::size_t i = 0; i < queries.size(); ++i) {
    Correspondence& c = out[i];
    c.valid = false;
    double u, v;
    if (!grid.Project(queries[i], u, v)) continue;
    const int u0 = static_cast<int>(std::floor(u)), v0 = static_cast<int>(std::floor(v));
    const double a = u - u0, b = v - v0;
    const std::int32_t corner[4] = {grid.At(u0, v0), grid.At(u0 + 1, v0), grid.At(u0, v0 + 1),
                                    grid.At(u0 + 1, v0 + 1)};
    const double weight[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
    bool complete = true;
    for (std::int32_t k : corner) complete = complete && k >= 0 && surface.valid[k];
    if (!complete) continue;
    Vec3 bilinear = Vec3::Zero(), normal = Vec3::Zero();
    double curvature = 0.0;
    Vec3 n[4];
    for (int k = 0; k < 4; ++k) {
      n[k] = surface.normals[corner[k]];
      // Unoriented normals: make the four agree before blending them.
      if (k > 0 && n[k].dot(n[0]) < 0.0) n[k] = -n[k];
      bilinear += weight[k] * points[corner[k]];
      normal += weight[k] * n[k];
      curvature += weight[k] * surface.curvature[corner[k]];
    }
    Vec3 point = bilinear;
    if (interpolation_ == Interpolation::kPhong) {
      Vec3 phong = Vec3::Zero();
      for (int k = 0; k < 4; ++k) {
        phong += weight[k] * (bilinear - (bilinear - points[corner[k]]).dot(n[k]) * n[k]);
      }
      point = (1.0 - alpha_) * bilinear + alpha_ * phong;
    }
    if (!(normal.norm() > 0.0)) continue;
    c.point = point;
    c.normal = normal.normalized();
    c.curvature = curvature;
    c.valid = true;
  }
}

}  // namespace mlsreg
