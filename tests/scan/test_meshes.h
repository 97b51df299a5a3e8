// Meshes for the scanner's tests, with exactly known geometry.
#pragma once

#include <cmath>
#include <numbers>

#include "mlsreg/core/triangle_mesh.h"

namespace mlsreg::scan {

// A UV sphere of `radius` around `center`: vertices lie exactly on the sphere.
inline TriangleMesh UvSphere(const Vec3& center, double radius, int rings, int segments) {
  TriangleMesh mesh;
  for (int i = 0; i <= rings; ++i) {
    const double theta = std::numbers::pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * std::numbers::pi * j / segments;
      mesh.vertices.push_back(center + radius * Vec3(std::sin(theta) * std::cos(phi),
                                                     std::cos(theta),
                                                     std::sin(theta) * std::sin(phi)));
    }
  }
  auto at = [&](int i, int j) { return static_cast<std::uint32_t>(i * segments + j % segments); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return mesh;
}

}  // namespace mlsreg::scan
