#include "scan/street_scene.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "scan/mesh_builder.h"
#include "scan/seeded_random.h"

namespace mlsreg::scan {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kGroundMargin = 90.0;  // ground beyond the street's ends and to either side
constexpr double kBuildingMargin = 60.0;

double Radians(double deg) { return deg * kPi / 180.0; }

// Road coordinates of an object: a rigid frame at (s, u) on the ground, x along the road.
Matrix4 RoadPlacement(const StreetLayout& layout, double s, double u, double z, double yaw = 0.0) {
  return YawPlacement(layout.World(s, u, z), layout.Heading(s) + yaw);
}

// The ground as grids of shared vertices: the road between the curbs, the two sides out to
// kGroundMargin, and the curbs' vertical faces between them.
void AddGround(const StreetLayout& layout, TriangleMesh& mesh) {
  std::vector<double> s_steps;
  for (double s = -kGroundMargin; s < layout.length_m + kGroundMargin; s += 2.0) {
    s_steps.push_back(s);
  }
  s_steps.push_back(layout.length_m + kGroundMargin);
  // The curb ramps down to the road over 0.3 m at a side street's edges.
  for (const auto& [start, end] : layout.cross_streets) {
    s_steps.insert(s_steps.end(), {start, start + 0.3, end - 0.3, end});
  }
  std::sort(s_steps.begin(), s_steps.end());
  s_steps.erase(std::unique(s_steps.begin(), s_steps.end(),
                            [](double a, double b) { return std::abs(a - b) < 1e-6; }),
                s_steps.end());
  const double w = layout.road_half_width_m;
  std::vector<double> road_u;
  const int half_cells = static_cast<int>(std::ceil(w / 1.0));
  for (int k = -half_cells; k <= half_cells; ++k) road_u.push_back(w * k / half_cells);
  std::vector<double> side_u;  // distances from the curb outward
  for (double d = 0.0; d < 20.0 - w; d += 1.0) side_u.push_back(d);
  for (double d = 20.0 - w; d < kGroundMargin - w; d += 3.0) side_u.push_back(d);
  side_u.push_back(kGroundMargin - w);

  // Heights at the curb: the road edge below, the sidewalk edge on top.
  auto grid = [&](const std::vector<double>& us, auto height_at) {
    const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
    const auto columns = static_cast<std::uint32_t>(us.size());
    for (double s : s_steps) {
      for (double u : us) mesh.vertices.push_back(layout.World(s, u, height_at(s, u)));
    }
    for (std::uint32_t i = 0; i + 1 < s_steps.size(); ++i) {
      for (std::uint32_t j = 0; j + 1 < columns; ++j) {
        const std::uint32_t a = base + i * columns + j, b = a + columns;
        mesh.triangles.push_back({a, b, b + 1});
        mesh.triangles.push_back({a, b + 1, a + 1});
      }
    }
  };
  grid(road_u, [&](double s, double u) { return layout.SurfaceHeight(s, u); });
  for (double side : {1.0, -1.0}) {
    std::vector<double> us;
    for (double d : side_u) us.push_back(side * (w + d));
    if (side < 0) std::reverse(us.begin(), us.end());
    grid(us, [&](double s, double u) {
      // At the curb line itself, the sidewalk's edge (SurfaceHeight gives the road there).
      const double outside = std::max(std::abs(u), w + 1e-9);
      return layout.SurfaceHeight(s, std::copysign(outside, u));
    });
  }
  if (layout.curb_height_m <= 0.0) return;
  MeshBuilder builder(mesh);
  for (double side : {1.0, -1.0}) {
    const double u = side * w, outside = side * (w + 1e-9);
    for (std::size_t i = 0; i + 1 < s_steps.size(); ++i) {
      const double s0 = s_steps[i], s1 = s_steps[i + 1];
      if (layout.CurbHeight(s0) == 0.0 && layout.CurbHeight(s1) == 0.0) continue;
      builder.AddQuad(layout.World(s0, u, layout.SurfaceHeight(s0, u)),
                      layout.World(s1, u, layout.SurfaceHeight(s1, u)),
                      layout.World(s1, u, layout.SurfaceHeight(s1, outside)),
                      layout.World(s0, u, layout.SurfaceHeight(s0, outside)));
    }
  }
}

// A rectangular recess in a façade: [a0, a1] along it, [b0, b1] in height, `depth` deep.
struct Recess {
  double a0, a1, b0, b1, depth;
};

struct BuildingSpec {
  double side = 1.0;         // +1 left of the road, -1 right
  double s0 = 0.0, s1 = 10;  // extent along the road
  double offset = 10.0;      // centreline to façade
  double depth = 12.0;
  double height = 12.0;  // above the sidewalk at the façade
  bool windows = true;
  double window_pitch = 3.0;  // between window columns
  bool door = true;
  bool shop_front = false;
};

// A box building whose street façade (the side facing the road) has recessed windows and doors.
void AddBuilding(const StreetLayout& layout, const BuildingSpec& spec, SeededRandom& random,
                 TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double s_center = 0.5 * (spec.s0 + spec.s1), half = 0.5 * (spec.s1 - spec.s0);
  const Matrix4 placement = RoadPlacement(layout, s_center, 0.0, 0.0);
  auto at = [&](double x, double y, double z) {
    return Vec3(placement.topLeftCorner<3, 3>() * Vec3(x, y, z) + placement.topRightCorner<3, 1>());
  };
  const double sigma = spec.side;
  const double y_front = sigma * spec.offset, y_back = sigma * (spec.offset + spec.depth);
  const double ground = layout.SurfaceHeight(s_center, y_front);
  double lowest = ground;
  for (double s : {spec.s0, spec.s1}) {
    for (double y : {y_front, y_back}) lowest = std::min(lowest, layout.SurfaceHeight(s, y));
  }
  const double z0 = lowest - 0.5, z1 = ground + spec.height;
  // Back, ends and roof: plain.
  builder.AddQuad(at(-half, y_back, z0), at(half, y_back, z0), at(half, y_back, z1),
                  at(-half, y_back, z1));
  for (double x : {-half, half}) {
    builder.AddQuad(at(x, y_front, z0), at(x, y_back, z0), at(x, y_back, z1), at(x, y_front, z1));
  }
  builder.AddQuad(at(-half, y_front, z1), at(half, y_front, z1), at(half, y_back, z1),
                  at(-half, y_back, z1));

  // The façade's recesses, in façade coordinates (a = x, b = z).
  std::vector<Recess> recesses;
  const double width = 2.0 * half;
  const double recess_depth = random.Uniform(0.12, 0.3);
  double door_a0 = 1e9, door_a1 = -1e9;
  if (spec.door && width > 4.0) {
    const double door_width = random.Uniform(1.1, 1.8);
    door_a0 = random.Uniform(-half + 0.8, half - 0.8 - door_width);
    door_a1 = door_a0 + door_width;
    recesses.push_back(
        {door_a0, door_a1, ground, ground + random.Uniform(2.2, 2.6), random.Uniform(0.3, 0.6)});
  }
  if (spec.windows) {
    const int columns = static_cast<int>((width - 1.0) / spec.window_pitch);
    const double window_width = std::min(random.Uniform(1.0, 1.6), spec.window_pitch - 0.6);
    const double window_height = random.Uniform(1.3, 1.8);
    const double floor_height = random.Uniform(2.9, 3.4);
    const double first = -0.5 * (columns - 1) * spec.window_pitch;
    // Ground floor: shop windows or ordinary ones, never over the door.
    for (int c = 0; c < columns; ++c) {
      const double center = first + c * spec.window_pitch;
      double a0 = center - 0.5 * window_width, a1 = center + 0.5 * window_width;
      double b0 = ground + 0.9, b1 = ground + 0.9 + window_height;
      if (spec.shop_front) {
        a0 = center - 0.5 * (spec.window_pitch - 0.5);
        a1 = center + 0.5 * (spec.window_pitch - 0.5);
        b0 = ground + 0.5;
        b1 = ground + 2.7;
      }
      if (a1 > door_a0 - 0.3 && a0 < door_a1 + 0.3) continue;
      if (a0 < -half + 0.3 || a1 > half - 0.3) continue;
      recesses.push_back({a0, a1, b0, b1, recess_depth});
    }
    for (double floor = ground + 4.0; floor + 0.9 + window_height < z1 - 0.6;
         floor += floor_height) {
      for (int c = 0; c < columns; ++c) {
        const double center = first + c * spec.window_pitch;
        if (center - 0.5 * window_width < -half + 0.3) continue;
        recesses.push_back({center - 0.5 * window_width, center + 0.5 * window_width, floor + 0.9,
                            floor + 0.9 + window_height, recess_depth});
      }
    }
  }
  // The façade wall: the cells between the recesses' edges that no recess covers, merged along
  // each band.
  std::vector<double> as = {-half, half}, bs = {z0, z1};
  for (const Recess& r : recesses) {
    as.insert(as.end(), {r.a0, r.a1});
    bs.insert(bs.end(), {r.b0, r.b1});
  }
  std::sort(as.begin(), as.end());
  as.erase(std::unique(as.begin(), as.end()), as.end());
  std::sort(bs.begin(), bs.end());
  bs.erase(std::unique(bs.begin(), bs.end()), bs.end());
  for (std::size_t j = 0; j + 1 < bs.size(); ++j) {
    const double bm = 0.5 * (bs[j] + bs[j + 1]);
    std::size_t i = 0;
    while (i + 1 < as.size()) {
      auto covered = [&](std::size_t k) {
        const double am = 0.5 * (as[k] + as[k + 1]);
        return std::any_of(recesses.begin(), recesses.end(), [&](const Recess& r) {
          return am > r.a0 && am < r.a1 && bm > r.b0 && bm < r.b1;
        });
      };
      if (covered(i)) {
        ++i;
        continue;
      }
      std::size_t end = i + 1;
      while (end + 1 < as.size() && !covered(end)) ++end;
      builder.AddQuad(at(as[i], y_front, bs[j]), at(as[end], y_front, bs[j]),
                      at(as[end], y_front, bs[j + 1]), at(as[i], y_front, bs[j + 1]));
      i = end;
    }
  }
  for (const Recess& r : recesses) {
    const double y_in = y_front + sigma * r.depth;
    builder.AddQuad(at(r.a0, y_in, r.b0), at(r.a1, y_in, r.b0), at(r.a1, y_in, r.b1),
                    at(r.a0, y_in, r.b1));
    builder.AddQuad(at(r.a0, y_front, r.b0), at(r.a1, y_front, r.b0), at(r.a1, y_in, r.b0),
                    at(r.a0, y_in, r.b0));
    builder.AddQuad(at(r.a0, y_front, r.b1), at(r.a1, y_front, r.b1), at(r.a1, y_in, r.b1),
                    at(r.a0, y_in, r.b1));
    for (double a : {r.a0, r.a1}) {
      builder.AddQuad(at(a, y_front, r.b0), at(a, y_in, r.b0), at(a, y_in, r.b1),
                      at(a, y_front, r.b1));
    }
  }
}

// A plain box on the ground at road coordinates: [s0, s1] x [u0, u1], `height` tall.
void AddGroundBox(const StreetLayout& layout, double s0, double s1, double u0, double u1,
                  double height, TriangleMesh& mesh) {
  const double s_center = 0.5 * (s0 + s1), u_center = 0.5 * (u0 + u1);
  const double ground = layout.SurfaceHeight(s_center, u_center);
  double lowest = ground;
  for (double s : {s0, s1}) {
    for (double u : {u0, u1}) lowest = std::min(lowest, layout.SurfaceHeight(s, u));
  }
  MeshBuilder(mesh).AddBox(RoadPlacement(layout, s_center, u_center, 0.0),
                           Vec3(-0.5 * (s1 - s0), -0.5 * (u1 - u0), lowest - 0.3),
                           Vec3(0.5 * (s1 - s0), 0.5 * (u1 - u0), ground + height));
}

// A tree: an 8-sided trunk and an irregular crown of many small random triangles (clutter that
// beams partly pass through).
void AddTree(const StreetLayout& layout, double s, double u, double scale, SeededRandom& random,
             TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double ground = layout.SurfaceHeight(s, u);
  const Matrix4 placement = RoadPlacement(layout, s, u, 0.0, random.Uniform(0.0, 2.0 * kPi));
  const double trunk_height = scale * random.Uniform(2.2, 3.5);
  const double rx = scale * random.Uniform(1.6, 2.6), ry = scale * random.Uniform(1.6, 2.6),
               rz = scale * random.Uniform(1.5, 2.8);
  builder.AddPrism(placement, scale * random.Uniform(0.12, 0.22), 8, ground - 0.3,
                   ground + trunk_height + 0.8 * rz);
  const Vec3 center(0.0, 0.0, ground + trunk_height + 0.8 * rz);
  const int leaves = static_cast<int>(scale * scale * random.Uniform(350.0, 600.0));
  auto direction = [&] {
    Vec3 d(random.Gaussian(), random.Gaussian(), random.Gaussian());
    return Vec3(d / std::max(d.norm(), 1e-9));
  };
  for (int k = 0; k < leaves; ++k) {
    const double radius = std::cbrt(random.Uniform(0.15, 1.0));  // mostly near the crown's shell
    const Vec3 p = center + radius * direction().cwiseProduct(Vec3(rx, ry, rz));
    const Vec3 e1 = random.Uniform(0.12, 0.35) * direction();
    const Vec3 e2 = random.Uniform(0.12, 0.35) * direction();
    auto world = [&](const Vec3& q) {
      return Vec3(placement.topLeftCorner<3, 3>() * q + placement.topRightCorner<3, 1>());
    };
    builder.AddTriangle(world(p), world(p + e1), world(p + e2));
  }
}

// A lamp post at the curb: a tall pole, an arm over the road and the lamp's head.
void AddLampPost(const StreetLayout& layout, double s, double side, SeededRandom& random,
                 TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double u = side * (layout.road_half_width_m + 0.45);
  const double ground = layout.SurfaceHeight(s, u);
  const Matrix4 placement = RoadPlacement(layout, s, u, 0.0);
  const double height = random.Uniform(7.0, 9.0);
  builder.AddPrism(placement, random.Uniform(0.08, 0.14), 8, ground - 0.3, ground + height);
  const double reach = random.Uniform(1.2, 2.2);
  const double y0 = side > 0 ? -reach : 0.0, y1 = side > 0 ? 0.0 : reach;
  builder.AddBox(placement, Vec3(-0.05, y0, ground + height - 0.1),
                 Vec3(0.05, y1, ground + height));
  const double tip = -side * reach;
  builder.AddBox(placement, Vec3(-0.18, tip - 0.3, ground + height - 0.3),
                 Vec3(0.18, tip + 0.3, ground + height - 0.08));
}

// A thin pole with a square sign facing along the road.
void AddSignPole(const StreetLayout& layout, double s, double u, SeededRandom& random,
                 TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double ground = layout.SurfaceHeight(s, u);
  const Matrix4 placement = RoadPlacement(layout, s, u, 0.0);
  const double height = random.Uniform(2.4, 3.2);
  builder.AddPrism(placement, 0.035, 8, ground - 0.3, ground + height);
  const double size = random.Uniform(0.5, 0.8);
  builder.AddBox(placement, Vec3(0.04, -0.5 * size, ground + height - size),
                 Vec3(0.07, 0.5 * size, ground + height));
}

// Cars along the side's parking lane; `occupancy` of it is taken (about).
void AddParkedCars(const StreetLayout& layout, double side, double occupancy, SeededRandom& random,
                   TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double lane = side * (layout.road_half_width_m - 1.1);
  double s = -20.0 + random.Uniform(0.0, 5.0);
  while (s < layout.length_m + 20.0) {
    if (!random.Chance(occupancy)) {  // an empty stretch
      s += random.Uniform(6.0, 20.0);
      continue;
    }
    const CarShape& car = kCarShapes[random.Below(std::size(kCarShapes))];
    if (layout.CrossesSideStreet(s, s + car.length, 3.0)) {  // no parking in the junction
      s += car.length;
      continue;
    }
    const double center = s + 0.5 * car.length;
    const double u = lane + random.Uniform(-0.15, 0.15);
    // Parked in the direction of its side's traffic (right-hand traffic).
    const double yaw = (side > 0 ? kPi : 0.0) + random.Uniform(-0.03, 0.03);
    AddCar(builder, RoadPlacement(layout, center, u, layout.SurfaceHeight(center, u), yaw), car);
    s += car.length + random.Uniform(0.8, 3.0);
  }
}

// A bush: a crown of small random triangles near the ground, no trunk.
void AddShrub(const StreetLayout& layout, double s, double u, SeededRandom& random,
              TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double ground = layout.SurfaceHeight(s, u);
  const Matrix4 placement = RoadPlacement(layout, s, u, 0.0, random.Uniform(0.0, 2.0 * kPi));
  const double rx = random.Uniform(0.6, 1.5), ry = random.Uniform(0.6, 1.5),
               rz = random.Uniform(0.5, 1.0);
  const Vec3 center(0.0, 0.0, ground + 0.8 * rz);
  const int leaves = static_cast<int>(random.Uniform(120.0, 260.0));
  for (int k = 0; k < leaves; ++k) {
    Vec3 d(random.Gaussian(), random.Gaussian(), random.Gaussian());
    d /= std::max(d.norm(), 1e-9);
    const Vec3 p = center + std::cbrt(random.Uniform(0.2, 1.0)) * d.cwiseProduct(Vec3(rx, ry, rz));
    Vec3 e1(random.Gaussian(), random.Gaussian(), random.Gaussian());
    Vec3 e2(random.Gaussian(), random.Gaussian(), random.Gaussian());
    e1 *= random.Uniform(0.08, 0.25) / std::max(e1.norm(), 1e-9);
    e2 *= random.Uniform(0.08, 0.25) / std::max(e2.norm(), 1e-9);
    auto world = [&](const Vec3& q) {
      return Vec3(placement.topLeftCorner<3, 3>() * q + placement.topRightCorner<3, 1>());
    };
    builder.AddTriangle(world(p), world(p + e1), world(p + e2));
  }
}

void BuildStreet(const StreetLayout& layout, SeededRandom& random, TriangleMesh& mesh) {
  const double w = layout.road_half_width_m;
  // The street's character: how far back the façades stand, how often buildings leave gaps,
  // how full the parking lanes are, how leafy it is.
  const double nearest_facade = random.Uniform(std::max(6.0, w + 2.0), 10.0);
  const double setback_spread = random.Uniform(2.0, 5.0);
  const double gap_chance = random.Uniform(0.25, 0.55);
  const double parking = random.Uniform(0.4, 0.85);
  const double leafiness = random.Uniform(0.3, 0.8);
  for (double side : {1.0, -1.0}) {
    // Front row: buildings with varied setbacks, adjacent or with gaps; walls, hedges or bushes
    // in some gaps and front yards.
    double s = -kBuildingMargin + random.Uniform(0.0, 10.0);
    while (s < layout.length_m + kBuildingMargin) {
      BuildingSpec b;
      b.side = side;
      b.s0 = s;
      b.s1 = s + random.Uniform(8.0, 32.0);
      b.offset = std::min(15.0, nearest_facade + random.Uniform(0.0, setback_spread));
      b.depth = random.Uniform(10.0, 20.0);
      b.height = random.Uniform(6.0, 24.0);
      b.window_pitch = random.Uniform(2.4, 4.0);
      b.windows = random.Chance(0.9);
      b.shop_front = random.Chance(0.3);
      // A side street ends the block: the building stops short of it, the next starts after.
      double next = b.s1;
      for (const auto& [start, end] : layout.cross_streets) {
        if (b.s1 > start - 1.0 && b.s0 < end + 1.0) {
          b.s1 = std::min(b.s1, start - 1.0);
          next = end + 1.0;
        }
      }
      if (b.s1 - b.s0 >= 6.0) {
        AddBuilding(layout, b, random, mesh);
        if (b.offset - w > 5.0 && random.Chance(leafiness)) {  // a front yard
          AddShrub(layout, random.Uniform(b.s0 + 1.0, b.s1 - 1.0),
                   side * random.Uniform(w + 3.0, b.offset - 1.0), random, mesh);
        }
      }
      s = next;
      if (next != b.s1) continue;
      if (random.Chance(gap_chance)) {
        const double gap = random.Uniform(3.0, 18.0);
        const double u0 = side * random.Uniform(w + 2.0, nearest_facade + 1.0);
        if (layout.CrossesSideStreet(s, s + gap, 1.0)) {
          // nothing in the side street
        } else if (random.Chance(0.5)) {
          const bool hedge = random.Chance(0.5);
          const double thickness = hedge ? random.Uniform(0.6, 1.0) : 0.3;
          AddGroundBox(layout, s + 0.2, s + gap - 0.2, std::min(u0, u0 + side * thickness),
                       std::max(u0, u0 + side * thickness),
                       hedge ? random.Uniform(0.8, 1.8) : random.Uniform(0.6, 1.4), mesh);
        } else if (random.Chance(leafiness)) {
          AddShrub(layout, s + 0.5 * gap, u0 + side * random.Uniform(1.0, 4.0), random, mesh);
        }
        s += gap;
      }
    }
    // A sparse back row, seen through the gaps.
    const int back = static_cast<int>((layout.length_m + 2 * kBuildingMargin) / 30.0);
    for (int k = 0; k < back; ++k) {
      const double s0 = random.Uniform(-kBuildingMargin, layout.length_m + kBuildingMargin);
      const double near = random.Uniform(26.0, 45.0), far = near + random.Uniform(10.0, 20.0);
      const double s1 = s0 + random.Uniform(15.0, 40.0), height = random.Uniform(8.0, 30.0);
      if (layout.CrossesSideStreet(s0, s1, 2.0)) continue;
      AddGroundBox(layout, s0, s1, std::min(side * near, side * far),
                   std::max(side * near, side * far), height, mesh);
    }
    AddParkedCars(layout, side, parking, random, mesh);
    // Lamp posts along the curb.
    for (double p = random.Uniform(0.0, 20.0); p < layout.length_m + 40.0;
         p += random.Uniform(22.0, 35.0)) {
      AddLampPost(layout, p, side, random, mesh);
    }
    // Stretches of street trees on the sidewalk, over the parked cars.
    double t = -30.0 + random.Uniform(0.0, 20.0);
    while (t < layout.length_m + 30.0) {
      const double stretch = random.Uniform(30.0, 80.0);
      if (random.Chance(leafiness)) {
        for (double p = t; p < t + stretch; p += random.Uniform(7.0, 12.0)) {
          const double u = side * (w + random.Uniform(1.1, 1.6));
          if (!layout.CrossesSideStreet(p, p, 3.0)) AddTree(layout, p, u, 1.0, random, mesh);
        }
      }
      t += stretch + random.Uniform(10.0, 40.0);
    }
  }
  // Signs and bins on either sidewalk.
  const int signs = static_cast<int>(layout.length_m / 30.0);
  for (int k = 0; k < signs; ++k) {
    const double side = random.Chance(0.5) ? 1.0 : -1.0;
    const double s = random.Uniform(-20.0, layout.length_m + 20.0);
    if (!layout.CrossesSideStreet(s, s, 1.0))
      AddSignPole(layout, s, side * (w + 0.35), random, mesh);
  }
  const int bins = static_cast<int>(layout.length_m / 40.0);
  for (int k = 0; k < bins; ++k) {
    const double side = random.Chance(0.5) ? 1.0 : -1.0;
    const double s = random.Uniform(-20.0, layout.length_m + 20.0);
    const double u = side * (w + random.Uniform(0.5, 1.0)), height = random.Uniform(0.9, 1.2);
    if (layout.CrossesSideStreet(s, s + 0.6, 1.0)) continue;
    AddGroundBox(layout, s, s + 0.6, u - 0.3, u + 0.3, height, mesh);
  }
}

void BuildCorridor(const StreetLayout& layout, SeededRandom& random, TriangleMesh& mesh) {
  for (double side : {1.0, -1.0}) {
    const double offset = layout.road_half_width_m + random.Uniform(1.5, 2.5);
    const double height = random.Uniform(8.0, 12.0);
    double s = -kBuildingMargin;
    while (s < layout.length_m + kBuildingMargin) {
      BuildingSpec b;
      b.side = side;
      b.s0 = s;
      b.s1 = s + random.Uniform(40.0, 90.0);
      b.offset = offset + random.Uniform(-0.2, 0.2);
      b.depth = 10.0;
      b.height = height + random.Uniform(-0.3, 0.3);
      b.windows = random.Chance(0.4);
      b.window_pitch = random.Uniform(6.0, 10.0);
      b.door = random.Chance(0.3);
      AddBuilding(layout, b, random, mesh);
      s = b.s1;
    }
  }
}

void BuildOpenRoad(const StreetLayout& layout, SeededRandom& random, TriangleMesh& mesh) {
  MeshBuilder builder(mesh);
  const double w = layout.road_half_width_m;
  // Utility poles along one side, with a cross-arm.
  const double side = random.Chance(0.5) ? 1.0 : -1.0;
  for (double s = random.Uniform(0.0, 30.0); s < layout.length_m + 60.0;
       s += random.Uniform(45.0, 70.0)) {
    const double u = side * (w + random.Uniform(2.0, 4.0));
    const double ground = layout.SurfaceHeight(s, u);
    const Matrix4 placement = RoadPlacement(layout, s, u, 0.0);
    const double height = random.Uniform(9.0, 10.5);
    builder.AddPrism(placement, 0.14, 8, ground - 0.3, ground + height);
    builder.AddBox(placement, Vec3(-0.06, -0.9, ground + height - 0.7),
                   Vec3(0.06, 0.9, ground + height - 0.55));
  }
  const int trees = 3 + static_cast<int>(random.Below(4));
  for (int k = 0; k < trees; ++k) {
    const double s = random.Uniform(-40.0, layout.length_m + 40.0);
    const double u = (random.Chance(0.5) ? 1.0 : -1.0) * random.Uniform(15.0, 45.0);
    AddTree(layout, s, u, random.Uniform(1.0, 1.4), random, mesh);
  }
  const int sheds = static_cast<int>(random.Below(3));
  for (int k = 0; k < sheds; ++k) {
    const double s = random.Uniform(0.0, layout.length_m);
    const double u = (random.Chance(0.5) ? 1.0 : -1.0) * random.Uniform(50.0, 75.0);
    AddGroundBox(layout, s, s + random.Uniform(8.0, 20.0), u, u + random.Uniform(6.0, 12.0),
                 random.Uniform(3.0, 6.0), mesh);
  }
}

}  // namespace

std::string StreetKindName(StreetKind kind) {
  switch (kind) {
    case StreetKind::kStreet:
      return "street";
    case StreetKind::kCorridor:
      return "corridor";
    case StreetKind::kOpenRoad:
      return "open_road";
  }
  return "street";
}

absl::StatusOr<StreetKind> ParseStreetKind(std::string_view name) {
  for (StreetKind kind : {StreetKind::kStreet, StreetKind::kCorridor, StreetKind::kOpenRoad}) {
    if (name == StreetKindName(kind)) return kind;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("--scene: '", std::string(name), "' is not one of street, corridor, open_road"));
}

double StreetLayout::Heading(double s) const {
  if (bend_angle_rad == 0.0 || s <= bend_start_m) return 0.0;
  if (s >= bend_start_m + bend_length_m) return bend_angle_rad;
  return bend_angle_rad * (s - bend_start_m) / bend_length_m;
}

Vec3 StreetLayout::World(double s, double u, double z) const {
  double x = s, y = 0.0;
  if (bend_angle_rad != 0.0 && s > bend_start_m) {
    const double curvature = bend_angle_rad / bend_length_m;
    const double theta = Heading(s);
    x = bend_start_m + std::sin(theta) / curvature;
    y = (1.0 - std::cos(theta)) / curvature;
    const double beyond = s - (bend_start_m + bend_length_m);
    if (beyond > 0.0) {
      x += beyond * std::cos(theta);
      y += beyond * std::sin(theta);
    }
  }
  const double theta = Heading(s);
  return Vec3(x - u * std::sin(theta), y + u * std::cos(theta), z);
}

double StreetLayout::TerrainHeight(double s, double u) const {
  double z = slope * s;
  for (int k = 0; k < 3; ++k) {
    z += wave_amplitude_m[k] * std::sin(2.0 * kPi * s / wave_length_m[k] + wave_phase[k]);
  }
  for (int k = 3; k < 5; ++k) {
    z += wave_amplitude_m[k] * std::sin(2.0 * kPi * u / wave_length_m[k] + wave_phase[k]) *
         (0.6 + 0.4 * std::sin(2.0 * kPi * s / 97.0 + wave_phase[k]));
  }
  return z;
}

double StreetLayout::SurfaceHeight(double s, double u) const {
  const double w = road_half_width_m;
  const double along = TerrainHeight(s, 0.0);
  if (std::abs(u) <= w) return along - camber * std::abs(u);
  const double edge = std::copysign(w, u);
  return along - camber * w + CurbHeight(s) + TerrainHeight(s, u) - TerrainHeight(s, edge);
}

double StreetLayout::CurbHeight(double s) const {
  return CrossesSideStreet(s, s) ? 0.0 : curb_height_m;
}

bool StreetLayout::CrossesSideStreet(double s0, double s1, double margin) const {
  for (const auto& [start, end] : cross_streets) {
    if (s1 > start - margin && s0 < end + margin) return true;
  }
  return false;
}

StreetLayout MakeStreetLayout(const StreetSceneOptions& options) {
  SeededRandom random(SubSeed(options.seed, 0x5354524545ULL + static_cast<int>(options.kind)));
  StreetLayout layout;
  layout.kind = options.kind;
  double across_amplitude = 0.15;
  switch (options.kind) {
    case StreetKind::kStreet:
      layout.length_m = random.Uniform(210.0, 290.0);
      layout.road_half_width_m = random.Uniform(5.0, 6.5);
      break;
    case StreetKind::kCorridor:
      layout.length_m = random.Uniform(200.0, 260.0);
      layout.road_half_width_m = random.Uniform(3.5, 4.5);
      break;
    case StreetKind::kOpenRoad:
      layout.length_m = random.Uniform(220.0, 300.0);
      layout.road_half_width_m = 3.6;
      layout.curb_height_m = 0.0;
      across_amplitude = 0.5;
      break;
  }
  // One gentle bend (radius at least 130 m) on most streets and open roads; corridors are
  // straight.
  if (options.kind != StreetKind::kCorridor && random.Chance(0.6)) {
    const double angle = Radians(random.Uniform(8.0, 25.0));
    layout.bend_angle_rad = random.Chance(0.5) ? angle : -angle;
    layout.bend_length_m = std::max(random.Uniform(60.0, 110.0), 130.0 * angle);
    layout.bend_start_m =
        random.Uniform(60.0, std::max(61.0, layout.length_m - layout.bend_length_m - 40.0));
  }
  if (options.kind == StreetKind::kStreet) {
    const int side_streets = static_cast<int>(random.Below(3));
    for (int k = 0; k < side_streets; ++k) {
      const double width = random.Uniform(10.0, 16.0);
      const double start = random.Uniform(40.0, layout.length_m - 40.0 - width);
      if (!layout.CrossesSideStreet(start, start + width, 20.0)) {
        layout.cross_streets.push_back({start, start + width});
      }
    }
  }
  layout.slope = random.Uniform(-0.02, 0.02);
  for (int k = 0; k < 3; ++k) {
    layout.wave_amplitude_m[k] = random.Uniform(0.03, 0.25);
    layout.wave_length_m[k] = random.Uniform(25.0, 90.0);
    layout.wave_phase[k] = random.Uniform(0.0, 2.0 * kPi);
  }
  for (int k = 3; k < 5; ++k) {
    layout.wave_amplitude_m[k] = random.Uniform(0.3, 1.0) * across_amplitude;
    layout.wave_length_m[k] = random.Uniform(30.0, 80.0);
    layout.wave_phase[k] = random.Uniform(0.0, 2.0 * kPi);
  }
  return layout;
}

TriangleMesh BuildStreetScene(const StreetSceneOptions& options) {
  const StreetLayout layout = MakeStreetLayout(options);
  SeededRandom random(SubSeed(options.seed, 0x4F424A454354ULL + static_cast<int>(options.kind)));
  TriangleMesh mesh;
  AddGround(layout, mesh);
  switch (options.kind) {
    case StreetKind::kStreet:
      BuildStreet(layout, random, mesh);
      break;
    case StreetKind::kCorridor:
      BuildCorridor(layout, random, mesh);
      break;
    case StreetKind::kOpenRoad:
      BuildOpenRoad(layout, random, mesh);
      break;
  }
  return mesh;
}

}  // namespace mlsreg::scan
