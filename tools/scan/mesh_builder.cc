#include "scan/mesh_builder.h"

#include <cmath>
#include <numbers>

namespace mlsreg::scan {
namespace {

Vec3 Apply(const Matrix4& m, const Vec3& p) {
  return m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>();
}

}  // namespace

void MeshBuilder::AddTriangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const auto base = static_cast<std::uint32_t>(mesh_.vertices.size());
  mesh_.vertices.push_back(a);
  mesh_.vertices.push_back(b);
  mesh_.vertices.push_back(c);
  mesh_.triangles.push_back({base, base + 1, base + 2});
}

void MeshBuilder::AddQuad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const auto base = static_cast<std::uint32_t>(mesh_.vertices.size());
  mesh_.vertices.push_back(a);
  mesh_.vertices.push_back(b);
  mesh_.vertices.push_back(c);
  mesh_.vertices.push_back(d);
  mesh_.triangles.push_back({base, base + 1, base + 2});
  mesh_.triangles.push_back({base, base + 2, base + 3});
}

void MeshBuilder::AddBox(const Matrix4& local_to_world, const Vec3& lo, const Vec3& hi) {
  Vec3 c[8];
  for (int i = 0; i < 8; ++i) {
    c[i] = Apply(local_to_world, Vec3((i & 1) ? hi.x() : lo.x(), (i & 2) ? hi.y() : lo.y(),
                                      (i & 4) ? hi.z() : lo.z()));
  }
  AddQuad(c[0], c[2], c[3], c[1]);  // bottom
  AddQuad(c[4], c[5], c[7], c[6]);  // top
  AddQuad(c[0], c[1], c[5], c[4]);  // -y
  AddQuad(c[2], c[6], c[7], c[3]);  // +y
  AddQuad(c[0], c[4], c[6], c[2]);  // -x
  AddQuad(c[1], c[3], c[7], c[5]);  // +x
}

void MeshBuilder::AddPrism(const Matrix4& local_to_world, double radius, int sides, double z0,
                           double z1) {
  std::vector<Vec3> bottom, top;
  for (int k = 0; k < sides; ++k) {
    const double a = 2.0 * std::numbers::pi * k / sides;
    bottom.push_back(Apply(local_to_world, Vec3(radius * std::cos(a), radius * std::sin(a), z0)));
    top.push_back(Apply(local_to_world, Vec3(radius * std::cos(a), radius * std::sin(a), z1)));
  }
  for (int k = 0; k < sides; ++k) {
    const int next = (k + 1) % sides;
    AddQuad(bottom[k], bottom[next], top[next], top[k]);
  }
  for (int k = 1; k + 1 < sides; ++k) {
    AddTriangle(bottom[0], bottom[k + 1], bottom[k]);
    AddTriangle(top[0], top[k], top[k + 1]);
  }
}

Matrix4 YawPlacement(const Vec3& origin, double yaw) {
  Matrix4 m = Matrix4::Identity();
  m(0, 0) = std::cos(yaw);
  m(0, 1) = -std::sin(yaw);
  m(1, 0) = std::sin(yaw);
  m(1, 1) = std::cos(yaw);
  m.topRightCorner<3, 1>() = origin;
  return m;
}

void AddCar(MeshBuilder& builder, const Matrix4& local_to_world, const CarShape& car) {
  const double half_length = 0.5 * car.length, half_width = 0.5 * car.width;
  builder.AddBox(local_to_world, Vec3(-half_length, -half_width, 0.3),
                 Vec3(half_length, half_width, car.body_top));
  const double cabin_x0 = -half_length + car.cabin_rear;
  builder.AddBox(local_to_world, Vec3(cabin_x0, -half_width + 0.08, car.body_top),
                 Vec3(cabin_x0 + car.cabin_length, half_width - 0.08, car.roof));
  constexpr double kWheel = 0.62, kTyre = 0.22;
  for (double x : {-half_length + 0.8, half_length - 0.8}) {
    for (double y : {-half_width + 0.05, half_width - 0.05 - kTyre}) {
      builder.AddBox(local_to_world, Vec3(x - 0.5 * kWheel, y, -0.05),
                     Vec3(x + 0.5 * kWheel, y + kTyre, kWheel - 0.05));
    }
  }
}

}  // namespace mlsreg::scan
