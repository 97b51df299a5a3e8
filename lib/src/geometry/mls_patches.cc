#include "mlsreg/geometry/mls_patches.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "absl/strings/str_format.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/geometry/neighbor_cache.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/wendland.h"

namespace mlsreg {
namespace {

// The height field and its gradient at (x, y), monomials ordered as in HeightField.
struct HeightWithGradient {
  double value, dx, dy;
};
HeightWithGradient EvaluateHeight(const std::array<double, 10>& c, double x, double y) {
  const double xx = x * x, xy = x * y, yy = y * y;
  return {c[0] + c[1] * x + c[2] * y + c[3] * xx + c[4] * xy + c[5] * yy + c[6] * xx * x +
              c[7] * xx * y + c[8] * x * yy + c[9] * yy * y,
          c[1] + 2.0 * c[3] * x + c[4] * y + 3.0 * c[6] * xx + 2.0 * c[7] * xy + c[8] * yy,
          c[2] + c[4] * x + 2.0 * c[5] * y + c[7] * xx + 2.0 * c[8] * xy + 3.0 * c[9] * yy};
}

// Whether the last fit's support (its samples of weight > 0) lies on one scan line of `sensor`:
// the directions from the sensor to the samples spread across the line they span (the middle
// principal spread, about their mean line of sight) by less than kOneScanLineSpreadPerStep of
// the sensor's angular step.
bool OnOneScanLine(const std::vector<Vec3>& points, const MlsProjector::Workspace& ws,
                   const SensorFinding& sensor) {
  const RadiusNeighbors& support = ws.gathered.samples;
  const auto direction = [&](std::size_t j) {
    return (points[support[j].first] - sensor.position).normalized();
  };
  Vec3 sight = Vec3::Zero();
  int count = 0;
  for (std::size_t j = 0; j < support.size(); ++j) {
    if (!(ws.weights[j] > 0.0)) continue;
    sight += direction(j);
    ++count;
  }
  if (count < 3 || !(sight.squaredNorm() > 0.0)) return false;
  sight.normalize();
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (std::size_t j = 0; j < support.size(); ++j) {
    if (!(ws.weights[j] > 0.0)) continue;
    const Vec3 u = direction(j);
    const Vec3 off_sight = u - u.dot(sight) * sight;
    spread.noalias() += off_sight * off_sight.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(spread / count,
                                                              Eigen::EigenvaluesOnly);
  // Ascending: about 0 along the mean line of sight, then across the scan line, then along it.
  const double across = std::sqrt(std::max(solver.eigenvalues()[1], 0.0));
  return across < MlsPatches::kOneScanLineSpreadPerStep * sensor.angular_step;
}

}  // namespace

MlsPatches::MlsPatches(const std::vector<Vec3>& points, const KdTree& tree, const MlsOptions& mls,
                       const std::optional<Vec3>& viewpoint,
                       const std::optional<SensorFinding>& scan_sensor)
    : points_(&points), mls_(mls), scan_sensor_(scan_sensor) {
  MlsOptions exact = mls;
  exact.seed_far_queries_from_nearest_sample = false;
  // An anchor's patch is the fit around wherever Algorithm 1 stops. Stopping once an iteration
  // moves it by less than kAnchorTolerancePerRadius instead of 1e-3 r moves the fit's centre by
  // about a hundredth of the support, where the fit barely changes, and saves over a third of the
  // iterations (4.1 instead of 6.6 per anchor on a tuning scan at sigma = 2 d, 1,637 anchors; the
  // tuning split's accuracy is unchanged within its spread).
  const bool default_tolerance = !(exact.tolerance > 0.0);
  const int steps = scan_sensor ? kMaxSupportGrowthSteps : 0;
  for (int step = 0; step <= steps; ++step) {
    if (default_tolerance) exact.tolerance = kAnchorTolerancePerRadius * exact.radius;
    projectors_.push_back(std::make_unique<MlsProjector>(points, tree, exact, viewpoint));
    // A grown support holds a few scan lines: they fix a plane, while a polynomial across them
    // would pass through each line and swing freely between them.
    exact.radius *= kSupportGrowth;
    exact.polynomial_degree = std::min(exact.polynomial_degree, 1);
  }
}
MlsPatches::MlsPatches(MlsPatches&&) noexcept = default;
MlsPatches& MlsPatches::operator=(MlsPatches&&) noexcept = default;
MlsPatches::~MlsPatches() = default;

absl::StatusOr<MlsPatches> MlsPatches::Build(const std::vector<Vec3>& points, const KdTree& tree,
                                             const MlsOptions& mls,
                                             const std::optional<Vec3>& viewpoint,
                                             PatchFitting fitting, int threads,
                                             const StopCheck& should_stop,
                                             const std::optional<SensorFinding>& scan_sensor) {
  if (!(mls.radius > 0.0)) return absl::InvalidArgumentError("MLS patches need a radius > 0");
  MlsPatches patches(points, tree, mls, viewpoint, scan_sensor);
  for (std::uint32_t i : VoxelRepresentatives(points, kAnchorSpacingPerRadius * mls.radius)) {
    patches.anchors_.push_back(points[i]);
  }
  const std::size_t count = patches.anchors_.size();
  // Default-initialised and filled front to back as patches are fitted (each takes the next
  // slot), so the pages of slots no fit takes are never touched: a one-shot registration fits a
  // fraction of the anchors.
  patches.patches_.reset(new Patch[count]);
  patches.slots_.reset(new std::uint32_t[count]);
  patches.next_slot_ = std::make_unique<std::atomic<std::uint32_t>>(0);
  patches.states_ = std::make_unique<std::atomic<std::uint8_t>[]>(count);
  for (std::size_t i = 0; i < count; ++i) patches.states_[i].store(kUnfitted);
  patches.anchor_tree_ = std::make_unique<KdTree>(patches.anchors_, threads);
  if (fitting == PatchFitting::kOnFirstUse) return patches;
  if (should_stop && should_stop()) return absl::CancelledError("MLS patch build cancelled");

  std::atomic<bool> fitted_one{false};
  const bool finished = ParallelForUntilStopped<MlsProjector::Workspace>(
      count, threads, should_stop,
      [&](std::size_t i, MlsProjector::Workspace& workspace) {
        Patch patch;
        const State outcome = patches.Fit(i, workspace, patch);
        if (IsFitted(outcome)) {
          patches.Store(i, patch);
          fitted_one.store(true, std::memory_order_relaxed);
        }
        patches.states_[i].store(outcome, std::memory_order_relaxed);
      },
      64);
  if (!finished) return absl::CancelledError("MLS patch build cancelled");
  if (!fitted_one.load()) {
    return absl::FailedPreconditionError(
        !scan_sensor
            ? std::string("no MLS patch could be fitted: the cloud has no neighbourhood of 3 "
                          "samples within r")
            : absl::StrFormat("no MLS patch could be fitted: the cloud has no neighbourhood of 3 "
                              "samples within r that spans a surface (nor within %.2g r)",
                              std::pow(kSupportGrowth, kMaxSupportGrowthSteps)));
  }
  return patches;
}

MlsPatches::Patch MlsPatches::PatchOf(const MlsLocalFit& fit, double growth) {
  Patch patch{fit.origin,       fit.frame.tangent_u,     fit.frame.tangent_v,
              fit.frame.normal, fit.height.coefficients, fit.frame.surface_variation};
  if (growth != 1.0) {
    // Fitted over (x, y) / (growth r) with heights in growth r: in units of r a monomial of
    // degree k takes growth^(1 - k).
    static constexpr int kMonomialDegree[10] = {0, 1, 1, 2, 2, 2, 3, 3, 3, 3};
    for (int k = 0; k < 10; ++k) patch.coefficients[k] *= std::pow(growth, 1 - kMonomialDegree[k]);
  }
  return patch;
}

MlsPatches::State MlsPatches::Fit(std::size_t i, MlsProjector::Workspace& workspace,
                                  Patch& out) const {
  double growth = 1.0;
  for (const std::unique_ptr<MlsProjector>& projector : projectors_) {
    const MlsProjection projection =
        scan_sensor_ ? projector->ProjectUnlessLine(anchors_[i], workspace, kFirstFitLineSpread)
                     : projector->Project(anchors_[i], workspace);
    if (projection.status == ProjectionStatus::kLineSupport) {
      growth *= kSupportGrowth;
      continue;
    }
    if (projection.status != ProjectionStatus::kOk) return kFailed;
    const Vec3& spread = workspace.last_fit.frame.eigenvalues;  // ascending
    if (!scan_sensor_ || spread[1] >= kMinSupportSpread * spread[2]) {
      out = PatchOf(workspace.last_fit, growth);
      return scan_sensor_ && OnOneScanLine(*points_, workspace, *scan_sensor_)
                 ? kFittedOnOneScanLine
                 : kFitted;
    }
    growth *= kSupportGrowth;
  }
  return kFailed;  // a line at every support
}

void MlsPatches::Store(std::size_t i, const Patch& patch) const {
  const std::uint32_t slot = next_slot_->fetch_add(1, std::memory_order_relaxed);
  patches_[slot] = patch;
  slots_[i] = slot;
}

MlsPatches::State MlsPatches::PatchAt(std::size_t i, Patch& out) const {
  std::atomic<std::uint8_t>& state = states_[i];
  std::uint8_t seen = state.load(std::memory_order_acquire);
  if (IsFitted(static_cast<State>(seen))) {
    out = patches_[slots_[i]];
    return static_cast<State>(seen);
  }
  if (seen == kFailed) return kFailed;
  // Unfitted, or another thread is fitting it: fit here (the fit is a pure function of the
  // anchor, so both threads get the same patch); only the thread that claims the patch stores it.
  thread_local MlsProjector::Workspace workspace;
  const State outcome = Fit(i, workspace, out);
  if (seen == kUnfitted &&
      state.compare_exchange_strong(seen, kFitting, std::memory_order_acquire)) {
    if (IsFitted(outcome)) Store(i, out);
    state.store(outcome, std::memory_order_release);
  }
  return outcome;
}

std::size_t MlsPatches::fitted() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < size(); ++i) {
    const std::uint8_t s = states_[i].load(std::memory_order_relaxed);
    n += IsFitted(static_cast<State>(s)) || s == kFailed;
  }
  return n;
}

MlsPatches::Blend MlsPatches::BlendAt(const Vec3& query, const Vec3& near, AnchorCache* cache,
                                      double beyond, int blended) const {
  const int k = std::clamp(blended, 1, kBlendedPatches);
  std::uint32_t index[kBlendedPatches + 1];
  double distance_squared[kBlendedPatches + 1];
  const std::size_t found =
      CachedKnn(*anchor_tree_, anchors_, near, k + 1, cache, index, distance_squared);
  Blend blend;
  if (found == 0) return blend;
  blend.nearest_distance = std::sqrt(distance_squared[0]);
  blend.nearest_anchor = index[0];
  // Beyond the surface's reach (a source sample outside the overlap): the caller refuses the
  // query, so fitting the far anchors' patches on first use would be work no answer reads.
  if (blend.nearest_distance > beyond) return blend;
  // The weights fall to zero at the (k+1)-th anchor, so a patch enters and leaves the blend with
  // weight 0 as the query moves.
  const std::size_t used = std::min<std::size_t>(found, k);
  const double support = found > static_cast<std::size_t>(k)
                             ? std::sqrt(distance_squared[k])
                             : 2.0 * std::sqrt(distance_squared[found - 1]) + mls_.radius;
  const double r = mls_.radius, inv_r = 1.0 / r;
  Vec3 reference_normal = Vec3::Zero();  // the first contributing patch's
  Vec3 point_sum = Vec3::Zero(), normal_sum = Vec3::Zero();
  double variation_sum = 0.0, weight_sum = 0.0;
  int contributing = 0;
  bool one_scan_line = false;
  Patch patch;
  for (std::size_t j = 0; j < used; ++j) {
    double w = WendlandWeight(std::sqrt(distance_squared[j]), support);
    if (j == 0 && !(w > 0.0)) w = 1.0;  // all k+1 equidistant: the nearest alone
    if (!(w > 0.0)) continue;
    const State fitted = PatchAt(index[j], patch);
    if (fitted == kFailed) continue;
    if (contributing == 0) reference_normal = patch.n;
    const Vec3 local = (query - patch.origin) * inv_r;
    const double x = local.dot(patch.u), y = local.dot(patch.v);
    const HeightWithGradient h = EvaluateHeight(patch.coefficients, x, y);
    Vec3 normal = (patch.n - h.dx * patch.u - h.dy * patch.v).normalized();
    if (normal.dot(reference_normal) < 0.0) normal = -normal;
    point_sum += w * (patch.origin + r * (x * patch.u + y * patch.v + h.value * patch.n));
    normal_sum += w * normal;
    variation_sum += w * patch.surface_variation;
    weight_sum += w;
    one_scan_line = one_scan_line || fitted == kFittedOnOneScanLine;
    ++contributing;
  }
  if (contributing == 0) return blend;
  MlsProjection& p = blend.projection;
  p.point = point_sum / weight_sum;
  p.normal = normal_sum.normalized();
  p.curvature = variation_sum / weight_sum;
  p.neighbors = contributing;
  p.iterations = 1;
  p.status = ProjectionStatus::kOk;
  p.one_scan_line = one_scan_line;
  blend.ok = p.point.allFinite() && p.normal.allFinite();
  return blend;
}

std::optional<MlsProjection> MlsPatches::SeededAt(std::uint32_t anchor) const {
  const Vec3& at = anchors_[anchor];
  Blend seeded = BlendAt(at, at);
  if (seeded.ok) {
    const Blend refined = BlendAt(at, seeded.projection.point);
    if (refined.ok) seeded = refined;
  }
  if (!seeded.ok) return std::nullopt;
  seeded.projection.seeded_from_nearest_sample = true;
  seeded.projection.iterations = 2;
  return seeded.projection;
}

MlsProjection MlsPatches::ProjectForJudging(const Vec3& query, AnchorCache* cache) const {
  const Blend blend = BlendAt(query, query, cache, mls_.radius, kJudgingPatches);
  if (blend.ok) return blend.projection;
  MlsProjection far;
  far.status = ProjectionStatus::kTooFewNeighbors;
  return far;
}

MlsProjection MlsPatches::Finish(const Vec3& query, const Vec3& near, bool seed_far_queries,
                                 int blends, AnchorCache* cache, SeedMemo* seed_memo) const {
  Blend blend = BlendAt(query, near, cache, mls_.radius);
  if (!blend.ok || blend.nearest_distance > mls_.radius) {
    MlsProjection far;
    far.status = ProjectionStatus::kTooFewNeighbors;
    if (!seed_far_queries || blend.nearest_anchor == kNoAnchor) return far;
    // As Algorithm 1 does for such queries: project a target sample near the query instead,
    // here the nearest anchor (a sample the blend has just found).
    const std::uint32_t anchor = blend.nearest_anchor;
    if (seed_memo == nullptr) return SeededAt(anchor).value_or(far);
    if (seed_memo->anchor != anchor) {
      seed_memo->anchor = anchor;
      seed_memo->projection = SeededAt(anchor).value_or(far);
    }
    return seed_memo->projection;
  }
  if (blends > 1) {
    // Patches chosen around the first estimate, which lies on the surface: the right ones even
    // when the query is well off the surface.
    const Blend refined = BlendAt(query, blend.projection.point, cache);
    if (refined.ok) {
      blend = refined;
      blend.projection.iterations = 2;
    }
  }
  return blend.projection;
}

MlsProjection MlsPatches::Project(const Vec3& query, bool seed_far_queries, AnchorCache* cache,
                                  SeedMemo* seed_memo) const {
  return Finish(query, query, seed_far_queries, 2, cache, seed_memo);
}

MlsProjection MlsPatches::ProjectNear(const Vec3& query, const Vec3& near, bool seed_far_queries,
                                      AnchorCache* cache) const {
  return Finish(query, near, seed_far_queries, 1, cache, nullptr);
}

std::size_t MlsPatches::MemoryBytes() const {
  return size() * (sizeof(Patch) + sizeof(std::uint32_t) + sizeof(std::atomic<std::uint8_t>)) +
         anchors_.capacity() * sizeof(Vec3) + projectors_.size() * sizeof(MlsProjector) +
         (anchor_tree_ ? anchor_tree_->MemoryBytes() : 0);
}

}  // namespace mlsreg
