// TriangleMesh: an indexed triangle mesh (read by mlsreg/io/mesh_io.h). Meshes are the input of
// the virtual scanner (tools/scan), not of registration.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;  // indices into `vertices`

  // Area-weighted centroid of the surface (the barycenter a turntable scanner circles).
  Vec3 SurfaceCentroid() const;
  // Radius of the smallest sphere around `center` holding every vertex.
  double BoundingRadius(const Vec3& center) const;
};

// At least one triangle, finite vertices, indices in range; the message says what and where.
absl::Status ValidateTriangleMesh(const TriangleMesh& mesh);

}  // namespace mlsreg
