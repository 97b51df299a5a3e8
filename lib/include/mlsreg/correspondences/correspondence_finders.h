// The correspondence policies: closest point (CP) and MLS projection.
#pragma once

#include <vector>

#include "mlsreg/correspondences/correspondence.h"
#include "mlsreg/geometry/mls_projector.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg {

// Classical ICP matching (paper Eq. 2): the nearest target sample, with the target's precomputed
// normal and surface variation. Invalid where the target's local analysis failed.
class ClosestPointFinder final : public CorrespondenceFinder {
 public:
  explicit ClosestPointFinder(const Target& target) : target_(target) {}
  void Find(std::span<const Vec3> queries, std::span<Correspondence> out) override;
  bool oriented_normals() const override { return target_.oriented(); }

 private:
  const Target& target_;
};

// MLS correspondences (paper Eq. 7): each query is projected onto the MLS surface of the target,
// by patches (MlsProjectionKind: the ones built with the target when their radius and degree are
// the ones asked for, otherwise patches built for this finder at its first Find) or by the exact
// Algorithm 1.
// With warm starts, the projection of sample i starts from the query projected onto the tangent
// plane of sample i's previous projection, when that projection was direct (not seeded from the
// nearest sample) and lies within the support radius of the query.
// What happens to queries with fewer than 3 target samples within r (paper Algorithm 1 cannot
// start there): seed them from their nearest sample until the registration first converges,
// then drop them (coarse to fine: robust start, and at the end only queries the MLS surface
// supports); always seed; or always drop (strict Algorithm 1).
enum class FarQueryPolicy { kSeedUntilConverged, kSeed, kDrop };

// How a query reaches the MLS surface: blended from the target's precomputed patches
// (geometry/mls_patches.h: a few nearest-neighbour lookups, about closest-point cost), or by the
// exact Algorithm 1 (the paper's reference: several radius searches and fits per query). The
// default uses the patches until the registration first converges and the exact projection,
// warm-started from them, for the fine phase: the exact method's accuracy at a fraction of its
// cost (on the tuning split the patches alone lose 10 % of median accuracy at 2 d).
enum class MlsProjectionKind { kPatchesThenExact, kPatches, kExact };

class MlsCorrespondenceFinder final : public CorrespondenceFinder {
 public:
  MlsCorrespondenceFinder(const Target& target, const MlsOptions& options, bool warm_start,
                          FarQueryPolicy far_queries = FarQueryPolicy::kSeedUntilConverged,
                          MlsProjectionKind projection = MlsProjectionKind::kPatchesThenExact);
  void Find(std::span<const Vec3> queries, std::span<Correspondence> out) override;
  bool oriented_normals() const override { return oriented_; }
  bool can_refine() const override { return far_queries_ == FarQueryPolicy::kSeedUntilConverged; }
  bool foot_points() const override { return true; }
  double analysis_radius() const override { return radius_; }
  void Refine() override;
  void KeepOnly(std::span<const std::uint32_t> kept) override;

  // Status of each sample's last projection (for statistics and tests).
  const std::vector<ProjectionStatus>& last_status() const { return status_; }
  // Total Algorithm 1 iterations (patch blends) spent in the last Find call.
  long last_iterations() const { return last_iterations_; }
  // The patches projections use; null for the exact Algorithm 1 (or before the first Find when
  // they are built for this finder).
  const MlsPatches* patches() const { return patches_; }

 private:
  // One per thread, each on its own cache lines: threads writing neighbours' vector headers or
  // counters would otherwise invalidate each other's caches at every query.
  struct alignas(64) ThreadState {
    MlsProjector::Workspace workspace;
    long iterations = 0;
  };
  // Queries [begin, end) of one Find, with that thread's workspace; false when stopped.
  bool FindRange(std::span<const Vec3> queries, std::span<Correspondence> out, std::size_t begin,
                 std::size_t end, ThreadState& state);
  // The projection of `query`, from `start` when warm.
  // The exact projection keeps the query's neighbourhood in `kept` for its next projection.
  MlsProjection ProjectOne(const Vec3& query, const Vec3* start, MlsProjector::Workspace& workspace,
                           MlsPatches::AnchorCache& anchors, MlsPatches::SeedMemo& seed,
                           KeptNeighborhood* kept) const;
  // Builds the patches this finder needs when the target's do not fit; false when stopped.
  bool EnsurePatches();

  const Target& target_;
  MlsProjector projector_;
  bool warm_start_;
  FarQueryPolicy far_queries_;
  MlsProjectionKind projection_;
  bool oriented_;
  double radius_;
  const MlsPatches* patches_ = nullptr;
  std::optional<MlsPatches> own_patches_;
  std::vector<ThreadState> threads_state_;
  std::vector<MlsProjection> previous_;
  // Per query: the patches' anchors nearest its last projection (valid for anchors_of_ only)
  std::vector<MlsPatches::AnchorCache> anchors_;
  std::vector<MlsPatches::SeedMemo> seeds_;  // and its last seeded projection when far
  const MlsPatches* anchors_of_ = nullptr;
  // Per query: the target samples around its last exact projection (MlsProjector::ProjectFrom),
  // dropped when larger than kMaxKeptSamples.
  std::vector<KeptNeighborhood> kept_;
  static constexpr std::size_t kMaxKeptSamples = 1024;
  std::vector<ProjectionStatus> status_;
  long last_iterations_ = 0;
};

// Reverse calibration (paper section 5.2.1): the query is projected into the target's depth image
// and its partner is interpolated from the four surrounding samples: bilinearly (RC-BL), or by
// Phong tessellation (RC-P, Boubekeur and Alexa 2008): the bilinear point projected onto the four
// samples' tangent planes, the projections blended with the same bilinear weights. Queries are in
// the target's (camera) frame; one outside the image or next to an empty pixel is invalid.
class ReverseCalibrationFinder final : public CorrespondenceFinder {
 public:
  enum class Interpolation { kBilinear, kPhong };
  // Phong tessellation's shape factor alpha: the result is (1 - alpha) bilinear + alpha Phong.
  // Boubekeur and Alexa recommend 3/4: with alpha = 1 the surface overshoots outward by about as
  // much as the bilinear blend falls short inward (measured on a sphere in the unit tests).
  static constexpr double kPhongShapeFactor = 0.75;
  // `target.grid()` must not be null.
  ReverseCalibrationFinder(const Target& target, Interpolation interpolation,
                           double phong_shape_factor = kPhongShapeFactor)
      : target_(target), interpolation_(interpolation), alpha_(phong_shape_factor) {}
  void Find(std::span<const Vec3> queries, std::span<Correspondence> out) override;
  bool oriented_normals() const override { return target_.oriented(); }

 private:
  const Target& target_;
  Interpolation interpolation_;
  double alpha_;
};

}  // namespace mlsreg
