// The LiDAR registration protocol: a car drives through a scene with the spinning sensor
// (lidar_scanner.h); pairs of its frames 3-12 m apart, with ground truth from the drive's poses,
// are written as `mlsreg eval` manifests, KITTI-like: source = the later frame, gt maps source
// points into the target sensor's frame (p_target = R p_source + t).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/triangle_mesh.h"
#include "scan/drive_path.h"
#include "scan/lidar_scanner.h"
#include "scan/movers.h"
#include "scan/street_scene.h"

namespace mlsreg::scan {

// What the sensor drives through: a static mesh, the drive, and where movers may go.
struct LidarScene {
  TriangleMesh mesh;
  Drive drive;
  std::vector<MoverLane> mover_lanes;
};

// A procedural street (street_scene.h) and the drive along it in its right-hand lane; movers in
// both lanes and on the sidewalks (the shoulder of an open road).
LidarScene MakeStreetLidarScene(const StreetSceneOptions& scene, const DriveOptions& drive);
// A user's mesh (metres, z up) and a straight drive through it (DriveThroughMesh); movers in a
// lane either side of the drive and 6 m out.
absl::StatusOr<LidarScene> MakeMeshLidarScene(TriangleMesh mesh, const DriveOptions& drive);

struct LidarProtocolOptions {
  LidarOptions lidar;  // its range_noise_sigma_m is not used: the scans are at noise_sigmas_m
  std::vector<double> noise_sigmas_m = {0.01, 0.03};
  std::vector<double> pair_gaps_m = {4.0, 8.0, 12.0};
  int pairs = 16;
  int movers = 0;          // moving objects along the drive (movers.h)
  std::uint64_t seed = 1;  // noise, dropouts and movers
  int threads = 1;
};

// InvalidArgument naming the flag of the first bad option: the scanner's (ValidateLidarOptions),
// --noise-m (some level, each 0-1 m), --pair-gaps (some, each > 0), --pairs (>= 1), --movers
// (>= 0), --threads (>= 1). Whether the gaps fit the drive is WriteLidarProtocol's to say.
absl::Status ValidateLidarProtocolOptions(const LidarProtocolOptions& options);

struct LidarProtocolSummary {
  double drive_length_m = 0.0;
  int frames = 0;  // of the drive
  int scans = 0;   // rendered: the frames in some pair
  std::size_t min_points = 0, max_points = 0;
  double mean_points = 0.0;
  int pairs = 0;
  std::vector<std::string> manifests;  // pairs.csv per noise level
};

// Renders the frames that some pair uses and writes, below `out_dir/name/`:
//   poses.csv                        frame, travelled_m, sensor_to_world (16 row-major numbers)
//                                    of every rendered frame
//   noise<sigma>/scan_<frame>.ply    the scan in its sensor's frame (binary PLY), range noise
//                                    sigma metres along the rays
//   noise<sigma>/pairs.csv           id,source,target,gt,distance_m,rotation_deg,scene,
//                                    noise_sigma_m,source_frame,target_frame
//   noise<sigma>/pairs_identity.csv  the same rows with init = identity (the no-prior start)
// The same scene, options and seed give the same bytes. `progress` (may be empty) is told each
// written scan.
absl::StatusOr<LidarProtocolSummary> WriteLidarProtocol(
    const LidarScene& scene, const std::string& name, const std::string& out_dir,
    const LidarProtocolOptions& options,
    const std::function<void(const std::string&)>& progress = {});

}  // namespace mlsreg::scan
