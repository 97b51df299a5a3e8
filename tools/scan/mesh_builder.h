// MeshBuilder: appends simple solids (quads, boxes, prisms) to a TriangleMesh. The procedural
// scenes (street_scene.h) and the moving objects (movers.h) are made of these.
#pragma once

#include <Eigen/Core>

#include "mlsreg/core/transform.h"
#include "mlsreg/core/triangle_mesh.h"

namespace mlsreg::scan {

class MeshBuilder {
 public:
  explicit MeshBuilder(TriangleMesh& mesh) : mesh_(mesh) {}

  void AddTriangle(const Vec3& a, const Vec3& b, const Vec3& c);
  // The quad a b c d (corners in order around it) as two triangles.
  void AddQuad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
  // The axis-aligned box [lo, hi] of a local frame, placed by `local_to_world`: six faces.
  void AddBox(const Matrix4& local_to_world, const Vec3& lo, const Vec3& hi);
  // A vertical prism with `sides` sides (a regular polygon of circumradius `radius` around the
  // local z axis) from local z0 to z1, placed by `local_to_world`, with both caps.
  void AddPrism(const Matrix4& local_to_world, double radius, int sides, double z0, double z1);

 private:
  TriangleMesh& mesh_;
};

// A rigid placement: rotation by `yaw` (radians, about z) then translation to `origin`.
Matrix4 YawPlacement(const Vec3& origin, double yaw);

// A car as boxes: a body over four wheels and a smaller cabin on top, in a local frame with x
// forward, y left, z up and the origin on the road under the car's centre.
struct CarShape {
  double length = 4.7, width = 1.8;
  double body_top = 1.0;  // the body spans 0.3 m above the road to here
  double roof = 1.45;     // the cabin spans body_top to here
  double cabin_length = 2.5;
  double cabin_rear = 0.9;  // from the car's rear to the cabin's
};
// Compact, sedan, SUV and van.
inline constexpr CarShape kCarShapes[] = {{3.9, 1.72, 0.95, 1.45, 2.0, 0.7},
                                          {4.7, 1.80, 1.00, 1.45, 2.5, 0.9},
                                          {4.8, 1.92, 1.15, 1.75, 2.9, 0.6},
                                          {5.2, 2.00, 1.25, 2.05, 3.9, 0.4}};
void AddCar(MeshBuilder& builder, const Matrix4& local_to_world, const CarShape& shape);

}  // namespace mlsreg::scan
