// Drive: where a car carrying the LiDAR is, frame by frame (10 frames a second, 0.7-1.5 m apart:
// 25-54 km/h), and the pairs of frames a registration protocol compares. The poses are of the
// car's base, on the road under the sensor (x forward, y left, z up); the sensor sits
// sensor_height_m above it (SensorPose).
#pragma once

#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/core/triangle_mesh.h"
#include "scan/ray_caster.h"
#include "scan/street_scene.h"

namespace mlsreg::scan {

struct Drive {
  std::vector<Matrix4> base_to_world;  // one per frame
  double frame_period_s = 0.1;
};

struct DriveOptions {
  int frames = 0;  // at most this many (0: as many as the street or mesh has room for)
  double min_step_m = 0.7, max_step_m = 1.5;  // travelled per frame (the speed varies smoothly)
  std::uint64_t seed = 1;
};

// InvalidArgument naming the flag: --frames (0 or >= 2), --step-m (0 < min <= max <= 5 m).
absl::Status ValidateDriveOptions(const DriveOptions& options);

// In the street's right-hand lane from 15 m after its start to 15 m before its end (or for
// options.frames frames), weaving a little within the lane with slight yaw changes, the base
// pitched and rolled by the road's slope and camber under the car's wheels.
Drive DriveAlongStreet(const StreetLayout& layout, const DriveOptions& options);

// A straight drive through a user's mesh (z up): along the longer horizontal side of its
// bounding box, through the box's centre, 5 % of the length in from either end, level, the base
// on the lowest surface under it (the box's bottom where there is none). FailedPrecondition when
// the mesh is shorter than 4 m.
absl::StatusOr<Drive> DriveThroughMesh(const TriangleMesh& mesh, const RayCaster& caster,
                                       const DriveOptions& options);

// The distance travelled from the first frame to each frame (along the base's positions).
std::vector<double> TravelledDistances(const Drive& drive);

// The sensor's pose: `height` above the base, along the base's z axis.
Matrix4 SensorPose(const Matrix4& base_to_world, double height);

struct FramePair {
  int source = 0;  // the later frame
  int target = 0;
  double gap_m = 0.0;  // the gap asked for; the frames' travelled distances differ by about it
};

// `count` pairs of frames spread evenly over the drive, the gaps taken in turn from `gaps_m`:
// each target frame is the one nearest its place, the source the later frame whose travelled
// distance is nearest the target's plus the gap. Pairs that would repeat are dropped, so fewer
// come back on a drive too short for `count` distinct pairs. InvalidArgument naming --pair-gaps
// when a gap is not positive or longer than the drive, --pairs when count < 1.
absl::StatusOr<std::vector<FramePair>> SelectFramePairs(const std::vector<double>& travelled,
                                                        const std::vector<double>& gaps_m,
                                                        int count);

}  // namespace mlsreg::scan
