#include "scan/drive_path.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "absl/strings/str_cat.h"
#include "scan/seeded_random.h"

namespace mlsreg::scan {
namespace {

constexpr double kPi = std::numbers::pi;

Matrix4 FrameFromAxes(const Vec3& position, const Vec3& forward, const Vec3& left_hint) {
  const Vec3 x = forward.normalized();
  const Vec3 y = (left_hint - left_hint.dot(x) * x).normalized();
  Matrix4 pose = Matrix4::Identity();
  pose.topLeftCorner<3, 3>().col(0) = x;
  pose.topLeftCorner<3, 3>().col(1) = y;
  pose.topLeftCorner<3, 3>().col(2) = x.cross(y);
  pose.topRightCorner<3, 1>() = position;
  return pose;
}

// Steps of a smoothly varying speed: a slow wave between the options' bounds.
class Speed {
 public:
  Speed(const DriveOptions& options, SeededRandom& random) : options_(options) {
    const double lo = options.min_step_m, hi = options.max_step_m;
    mean_ = random.Uniform(lo + 0.25 * (hi - lo), lo + 0.6 * (hi - lo));
    amplitude_ = random.Uniform(0.1, 0.4) * (hi - lo);
    period_ = random.Uniform(40.0, 120.0);
    phase_ = random.Uniform(0.0, 2.0 * kPi);
  }
  double Step(int frame) const {
    return std::clamp(mean_ + amplitude_ * std::sin(2.0 * kPi * frame / period_ + phase_),
                      options_.min_step_m, options_.max_step_m);
  }

 private:
  DriveOptions options_;
  double mean_, amplitude_, period_, phase_;
};

}  // namespace

absl::Status ValidateDriveOptions(const DriveOptions& options) {
  if (options.frames != 0 && options.frames < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("--frames: ", options.frames, " (0 for the whole street, else >= 2)"));
  }
  if (!(options.min_step_m > 0.0 && options.min_step_m <= options.max_step_m &&
        options.max_step_m <= 5.0)) {
    return absl::InvalidArgumentError(absl::StrCat("--step-m: ", options.min_step_m, "-",
                                                   options.max_step_m,
                                                   " m per frame (need 0 < min <= max <= 5)"));
  }
  return absl::OkStatus();
}

Drive DriveAlongStreet(const StreetLayout& layout, const DriveOptions& options) {
  SeededRandom random(SubSeed(options.seed, 0x44524956ULL));
  const Speed speed(options, random);
  // Lane keeping: a slow weave of up to 0.2 m and a faster 3 cm wobble (together at most about
  // 1.7 degrees off the road's heading), plus up to 0.4 degrees of yaw the path does not show.
  const double weave_length = random.Uniform(60.0, 100.0), weave_phase = random.Uniform(0, 2 * kPi);
  const double wobble_length = random.Uniform(20.0, 30.0),
               wobble_phase = random.Uniform(0, 2 * kPi);
  const double yaw_length = random.Uniform(15.0, 30.0), yaw_phase = random.Uniform(0, 2 * kPi);
  auto lateral = [&](double s) {
    return -layout.lane_offset_m + 0.2 * std::sin(2 * kPi * s / weave_length + weave_phase) +
           0.03 * std::sin(2 * kPi * s / wobble_length + wobble_phase);
  };
  auto on_road = [&](double s, double u) { return layout.World(s, u, layout.SurfaceHeight(s, u)); };
  Drive drive;
  const double end = layout.length_m - 15.0;
  double s = 15.0;
  for (int frame = 0; s <= end && (options.frames == 0 || frame < options.frames); ++frame) {
    const double u = lateral(s);
    // Pitch over the wheelbase, roll over the track.
    const Vec3 forward =
        on_road(s + 1.35, lateral(s + 1.35)) - on_road(s - 1.35, lateral(s - 1.35));
    const Vec3 left = on_road(s, u + 0.8) - on_road(s, u - 0.8);
    Matrix4 base = FrameFromAxes(on_road(s, u), forward, left);
    const double yaw = (0.4 * kPi / 180.0) * std::sin(2 * kPi * s / yaw_length + yaw_phase);
    base.topLeftCorner<3, 3>() =
        base.topLeftCorner<3, 3>() * Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
    drive.base_to_world.push_back(base);
    s += speed.Step(frame);
  }
  return drive;
}

absl::StatusOr<Drive> DriveThroughMesh(const TriangleMesh& mesh, const RayCaster& caster,
                                       const DriveOptions& options) {
  Vec3 lo = mesh.vertices.at(0), hi = lo;
  for (const Vec3& v : mesh.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const int axis = (hi.x() - lo.x()) >= (hi.y() - lo.y()) ? 0 : 1;
  const double length = hi[axis] - lo[axis];
  if (!(length >= 4.0)) {
    return absl::FailedPreconditionError(
        absl::StrCat("the mesh is ", length, " m long (z up, metres): too short to drive through"));
  }
  SeededRandom random(SubSeed(options.seed, 0x4D455348ULL));
  const Speed speed(options, random);
  const Vec3 center = 0.5 * (lo + hi);
  const Vec3 forward = axis == 0 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 left = Vec3::UnitZ().cross(forward);
  Drive drive;
  const double end = hi[axis] - 0.05 * length;
  double along = lo[axis] + 0.05 * length;
  for (int frame = 0; along <= end && (options.frames == 0 || frame < options.frames); ++frame) {
    Vec3 position = center;
    position[axis] = along;
    // The lowest surface below: follow the ray down through every hit.
    Vec3 origin(position.x(), position.y(), hi.z() + 1.0);
    double ground = lo.z();
    for (int k = 0; k < 256; ++k) {
      const std::optional<RayHit> hit = caster.Cast(origin, -Vec3::UnitZ());
      if (!hit) break;
      ground = origin.z() - hit->distance;
      origin.z() = ground - 1e-4;
    }
    position.z() = ground;
    drive.base_to_world.push_back(FrameFromAxes(position, forward, left));
    along += speed.Step(frame);
  }
  return drive;
}

std::vector<double> TravelledDistances(const Drive& drive) {
  std::vector<double> travelled;
  double total = 0.0;
  for (std::size_t k = 0; k < drive.base_to_world.size(); ++k) {
    if (k > 0) {
      total += (drive.base_to_world[k].topRightCorner<3, 1>() -
                drive.base_to_world[k - 1].topRightCorner<3, 1>())
                   .norm();
    }
    travelled.push_back(total);
  }
  return travelled;
}

Matrix4 SensorPose(const Matrix4& base_to_world, double height) {
  Matrix4 pose = base_to_world;
  pose.topRightCorner<3, 1>() += height * base_to_world.topLeftCorner<3, 3>().col(2);
  return pose;
}

absl::StatusOr<std::vector<FramePair>> SelectFramePairs(const std::vector<double>& travelled,
                                                        const std::vector<double>& gaps_m,
                                                        int count) {
  if (count < 1) return absl::InvalidArgumentError(absl::StrCat("--pairs: ", count, " (>= 1)"));
  if (gaps_m.empty()) return absl::InvalidArgumentError("--pair-gaps: no gap given");
  const double length = travelled.empty() ? 0.0 : travelled.back();
  double widest = 0.0;
  for (double gap : gaps_m) {
    if (!(gap > 0.0) || gap > length) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--pair-gaps: ", gap, " m is not in (0, the drive's length ", length, " m]"));
    }
    widest = std::max(widest, gap);
  }
  auto nearest = [&](double distance) {
    const auto it = std::lower_bound(travelled.begin(), travelled.end(), distance);
    if (it == travelled.end()) return static_cast<int>(travelled.size()) - 1;
    const int k = static_cast<int>(it - travelled.begin());
    if (k > 0 && distance - travelled[k - 1] < travelled[k] - distance) return k - 1;
    return k;
  };
  std::vector<FramePair> pairs;
  std::set<std::pair<int, int>> seen;
  for (int i = 0; i < count; ++i) {
    const double gap = gaps_m[i % gaps_m.size()];
    // Targets from the start to where the widest gap still fits.
    const double place = count == 1 ? 0.0 : (length - widest) * i / (count - 1);
    const int target = nearest(place);
    const int source = nearest(travelled[target] + gap);
    if (source <= target || !seen.insert({source, target}).second) continue;
    pairs.push_back({source, target, gap});
  }
  return pairs;
}

}  // namespace mlsreg::scan
