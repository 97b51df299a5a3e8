// StreetScene: seeded procedural urban scenes for the spinning-LiDAR mode, in metres with z up.
// A road runs along a centreline (about 200-300 m, straight or with one gentle bend) over a
// slightly sloped, undulating ground; everything is placed in road coordinates (s along the
// centreline, u to its left) and mapped to the world.
//   street     curbs (15 cm) and sidewalks, up to two side streets, façades 6-15 m from the
//   centreline on both sides with
//              varied setbacks, heights, recessed windows and doors, gaps between buildings
//              (with a row of buildings further back), lamp posts and sign poles (8-sided
//              prisms), parked cars, trees whose crowns are clutter of small random triangles,
//              low walls and hedges.
//   corridor   a straight road between two long continuous walls 5.5-7 m from the centreline,
//              few windows, nothing else: sliding along it is weakly constrained.
//   open_road  a road over open, rolling ground with a few utility poles and distant trees:
//              mostly ground, so sliding along the road is weakly constrained.
// The same options give the same mesh on every platform (SeededRandom, no std distributions).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/triangle_mesh.h"

namespace mlsreg::scan {

enum class StreetKind { kStreet, kCorridor, kOpenRoad };

std::string StreetKindName(StreetKind kind);  // "street", "corridor", "open_road"
// InvalidArgument naming the accepted names.
absl::StatusOr<StreetKind> ParseStreetKind(std::string_view name);

struct StreetSceneOptions {
  StreetKind kind = StreetKind::kStreet;
  std::uint64_t seed = 1;
};

// The road's geometry, drawn from the options: the centreline, the cross-section and the ground.
// The mesh is built on it, and a drive (drive_path.h) follows it.
struct StreetLayout {
  StreetKind kind = StreetKind::kStreet;
  double length_m = 250.0;         // of the centreline the buildings line (s in [0, length])
  double road_half_width_m = 5.5;  // centreline to curb
  double curb_height_m = 0.15;     // 0 on open_road (no curb)
  // Side streets crossing a street: [start, end] along s. The front and back rows, parked cars
  // and trees leave them open (long views to either side), and the curb drops to the road there.
  std::vector<std::pair<double, double>> cross_streets;
  double lane_offset_m = 1.75;  // centreline to the middle of a driving lane
  double camber = 0.02;         // the road falls by this per metre from the centreline
  // One circular bend: the heading turns by bend_angle_rad over [bend_start_m, bend_start_m +
  // bend_length_m] (angle 0: straight).
  double bend_start_m = 0.0, bend_length_m = 1.0, bend_angle_rad = 0.0;
  // Ground: a constant slope along s plus three gentle waves along s and two across.
  double slope = 0.0;
  double wave_amplitude_m[5] = {0, 0, 0, 0, 0};
  double wave_length_m[5] = {1, 1, 1, 1, 1};
  double wave_phase[5] = {0, 0, 0, 0, 0};

  double Heading(double s) const;  // of the centreline (radians from world +x)
  // The world point at road coordinates (s, u) and height z (metres above world z = 0).
  Vec3 World(double s, double u, double z) const;
  // The terrain under everything, before the road's camber and the curb.
  double TerrainHeight(double s, double u) const;
  // The curb's height at s: curb_height_m, 0 across a side street.
  double CurbHeight(double s) const;
  // Whether [s0, s1] overlaps a side street widened by `margin` on either side.
  bool CrossesSideStreet(double s0, double s1, double margin = 0.0) const;
  // The top of what is there: the road (|u| <= road_half_width_m), else the sidewalk / ground.
  double SurfaceHeight(double s, double u) const;
};

StreetLayout MakeStreetLayout(const StreetSceneOptions& options);

// The scene's mesh (a few hundred thousand triangles at most) around MakeStreetLayout(options).
// The ground extends 90 m beyond the street's ends and to either side, so that every beam of a
// sensor driving on it that points down within 80 m hits something.
TriangleMesh BuildStreetScene(const StreetSceneOptions& options);

}  // namespace mlsreg::scan
