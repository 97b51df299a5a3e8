// Correspondence and CorrespondenceFinder: how a source point finds its partner on the target.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <string_view>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"

namespace mlsreg {

// The partner of one source sample: a point on the target surface with its normal and surface
// variation. Not a target index: MLS and other surface models produce points between samples.
struct Correspondence {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
  double curvature = 0.0;
  bool valid = false;  // false: the finder could not produce a usable partner
};

// Policy interface. Find is called once per ICP iteration with the current (transformed) source
// samples; out[i] receives the partner of queries[i]. Implementations may keep per-sample state
// between calls (e.g. warm starts), so a finder serves one registration at a time.
class CorrespondenceFinder {
 public:
  virtual ~CorrespondenceFinder() = default;
  virtual void Find(std::span<const Vec3> queries, std::span<Correspondence> out) = 0;
  // Whether output normals have a meaningful sign (see CorrespondenceFilterOptions).
  virtual bool oriented_normals() const = 0;
  // Coarse-to-fine finders: while can_refine() is true the registration converges to the coarse
  // threshold, then calls Refine() and continues with the finer correspondences.
  virtual bool can_refine() const { return false; }
  virtual void Refine() {}
  // Whether partners are foot points along the surface normal that slide with their query (MLS),
  // rather than fixed target samples or points along a viewing ray. The point-to-plane step then
  // damps sliding (RegistrationOptions::tangential_damping).
  virtual bool foot_points() const { return false; }
  // The radius at which the source's normals and surface variation are analysed, so that the
  // curvature filter compares like with like: the scale of this policy's partners (MLS: its
  // support radius); 0 for the target's own analysis radius (its normals and curvature).
  virtual double analysis_radius() const { return 0.0; }
  // The registration goes on with only these queries (indices into the last Find's, ascending):
  // the next Find gets them in this order. Finders that keep per-query state (warm starts)
  // keep theirs for these queries; stateless finders have nothing to do.
  virtual void KeepOnly(std::span<const std::uint32_t> /*kept*/) {}

  // Finders whose queries are expensive (MLS) ask this while they search and return early, with
  // the rest of `out` unset, once it says stop; the caller then asks it too and stops.
  void set_should_stop(StopCheck check) { should_stop_ = std::move(check); }
  // Threads that split each Find's queries; partners do not depend on the count.
  void set_threads(int threads) { threads_ = std::max(1, threads); }

 protected:
  StopCheck should_stop_;
  int threads_ = 1;
};

}  // namespace mlsreg
