#include "scan/movers.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "scan/mesh_builder.h"
#include "scan/seeded_random.h"

namespace mlsreg::scan {
namespace {

// The base pose at travelled distance `distance`: the position interpolated between the frames
// around it, the orientation of the nearer one.
Matrix4 PoseAtDistance(const Drive& drive, const std::vector<double>& travelled, double distance) {
  const auto it = std::upper_bound(travelled.begin(), travelled.end(), distance);
  const std::size_t next = std::min<std::size_t>(it - travelled.begin(), travelled.size() - 1);
  const std::size_t previous = next == 0 ? 0 : next - 1;
  const double span = travelled[next] - travelled[previous];
  const double f = span > 0.0 ? std::clamp((distance - travelled[previous]) / span, 0.0, 1.0) : 0.0;
  Matrix4 pose = drive.base_to_world[f < 0.5 ? previous : next];
  pose.topRightCorner<3, 1>() = (1.0 - f) * drive.base_to_world[previous].topRightCorner<3, 1>() +
                                f * drive.base_to_world[next].topRightCorner<3, 1>();
  return pose;
}

}  // namespace

std::vector<Mover> PlaceMovers(const std::vector<MoverLane>& lanes, int count, double length_m,
                               double ego_speed_mps, std::uint64_t seed) {
  std::vector<Mover> movers;
  if (lanes.empty()) return movers;
  SeededRandom random(SubSeed(seed, 0x4D4F564552ULL));
  for (int k = 0; k < count; ++k) {
    Mover m;
    m.lane = static_cast<int>(random.Below(lanes.size()));
    const MoverLane& lane = lanes[m.lane];
    m.start_m = random.Uniform(0.0, length_m);
    if (lane.cars) {
      m.speed_mps = lane.direction > 0 ? ego_speed_mps * random.Uniform(0.8, 1.2)
                                       : -random.Uniform(7.0, 14.0);
      m.shape = static_cast<int>(random.Below(std::size(kCarShapes)));
    } else {
      m.speed_mps = (random.Chance(0.5) ? 1.0 : -1.0) * random.Uniform(1.0, 1.6);
      m.shape = static_cast<int>(random.Uniform(155.0, 192.0));
    }
    movers.push_back(m);
  }
  return movers;
}

TriangleMesh MoversAt(const std::vector<Mover>& movers, const std::vector<MoverLane>& lanes,
                      const Drive& drive, const std::vector<double>& travelled, int frame,
                      double keep_clear_m) {
  TriangleMesh mesh;
  if (drive.base_to_world.empty()) return mesh;
  MeshBuilder builder(mesh);
  const double time = frame * drive.frame_period_s;
  const Vec3 ego = drive.base_to_world[frame].topRightCorner<3, 1>();
  for (const Mover& m : movers) {
    const double distance = m.start_m + m.speed_mps * time;
    if (distance < 0.0 || distance > travelled.back()) continue;
    const MoverLane& lane = lanes[m.lane];
    Matrix4 pose = PoseAtDistance(drive, travelled, distance);
    pose.topRightCorner<3, 1>() +=
        pose.topLeftCorner<3, 3>() * Vec3(0.0, lane.lateral_m, lane.height_m);
    if ((pose.topRightCorner<3, 1>() - ego).norm() < (lane.cars ? keep_clear_m : 2.0)) continue;
    const bool backward = m.speed_mps < 0.0;
    if (backward) {
      pose.topLeftCorner<3, 3>() =
          pose.topLeftCorner<3, 3>() *
          Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitZ()).toRotationMatrix();
    }
    if (lane.cars) {
      AddCar(builder, pose, kCarShapes[m.shape]);
    } else {
      builder.AddBox(pose, Vec3(-0.2, -0.27, -0.1), Vec3(0.2, 0.27, m.shape / 100.0));
    }
  }
  return mesh;
}

}  // namespace mlsreg::scan
