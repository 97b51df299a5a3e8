#include "mlsreg/core/triangle_mesh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace mlsreg {

Vec3 TriangleMesh::SurfaceCentroid() const {
  Vec3 sum = Vec3::Zero();
  double area = 0.0;
  for (const auto& t : triangles) {
    const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
    const double w = 0.5 * (b - a).cross(c - a).norm();
    sum += w * (a + b + c) / 3.0;
    area += w;
  }
  return area > 0.0 ? Vec3(sum / area) : Vec3::Zero();
}

double TriangleMesh::BoundingRadius(const Vec3& center) const {
  double r2 = 0.0;
  for (const Vec3& v : vertices) r2 = std::max(r2, (v - center).squaredNorm());
  return std::sqrt(r2);
}

absl::Status ValidateTriangleMesh(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) return absl::InvalidArgumentError("mesh: it has no triangles");
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!mesh.vertices[i].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("mesh: vertex ", i, " is not finite"));
    }
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (std::uint32_t index : mesh.triangles[t]) {
      if (index >= mesh.vertices.size()) {
        return absl::InvalidArgumentError(absl::StrCat("mesh: triangle ", t, " refers to vertex ",
                                                       index, " of ", mesh.vertices.size()));
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace mlsreg
