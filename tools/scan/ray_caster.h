// RayCaster: first-hit ray queries against a triangle mesh, backed by Embree 3.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include "absl/status/statusor.h"
#include "mlsreg/core/triangle_mesh.h"

namespace mlsreg::scan {

struct RayHit {
  double distance = 0.0;  // along the (unit) ray direction
  Vec3 normal;            // unit geometric normal of the hit triangle, facing the ray's origin
  std::uint32_t triangle = 0;
};

class RayCaster {
 public:
  // Builds the acceleration structure (once; queries are then thread-safe).
  static absl::StatusOr<std::unique_ptr<RayCaster>> Build(const TriangleMesh& mesh);
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;

  // The closest hit along origin + t * direction, t > 0 (direction must be unit length), or none.
  // The distance is refined in double precision against the hit triangle's plane.
  std::optional<RayHit> Cast(const Vec3& origin, const Vec3& direction) const;

 private:
  struct Embree;
  explicit RayCaster(const TriangleMesh& mesh);
  const TriangleMesh& mesh_;
  std::unique_ptr<Embree> embree_;
};

}  // namespace mlsreg::scan
