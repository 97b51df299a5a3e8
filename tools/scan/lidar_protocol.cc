#include "scan/lidar_protocol.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "scan/seeded_random.h"

namespace mlsreg::scan {
namespace {

absl::Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  return absl::OkStatus();
}

std::string NoiseTag(double sigma_m) { return absl::StrFormat("noise%g", sigma_m); }
std::string ScanFile(int frame) { return absl::StrFormat("scan_%06d.ply", frame); }

}  // namespace

LidarScene MakeStreetLidarScene(const StreetSceneOptions& scene, const DriveOptions& drive) {
  const StreetLayout layout = MakeStreetLayout(scene);
  LidarScene result;
  result.mesh = BuildStreetScene(scene);
  result.drive = DriveAlongStreet(layout, drive);
  const double w = layout.road_half_width_m, lane = layout.lane_offset_m;
  const double sidewalk = layout.curb_height_m - layout.camber * (w - lane);
  result.mover_lanes = {{0.0, 0.0, true, 1.0}, {2.0 * lane, 0.0, true, -1.0}};
  result.mover_lanes.push_back({lane - (w + 1.0), sidewalk, false, 1.0});
  if (scene.kind != StreetKind::kOpenRoad) {
    result.mover_lanes.push_back({lane + w + 1.0, sidewalk, false, 1.0});
  }
  return result;
}

absl::StatusOr<LidarScene> MakeMeshLidarScene(TriangleMesh mesh, const DriveOptions& drive) {
  LidarScene result;
  result.mesh = std::move(mesh);
  absl::StatusOr<std::unique_ptr<RayCaster>> caster = RayCaster::Build(result.mesh);
  if (!caster.ok()) return caster.status();
  absl::StatusOr<Drive> path = DriveThroughMesh(result.mesh, **caster, drive);
  if (!path.ok()) return path.status();
  result.drive = *std::move(path);
  result.mover_lanes = {{0.0, 0.0, true, 1.0},
                        {3.5, 0.0, true, -1.0},
                        {6.0, 0.0, false, 1.0},
                        {-6.0, 0.0, false, 1.0}};
  return result;
}

absl::Status ValidateLidarProtocolOptions(const LidarProtocolOptions& options) {
  LidarOptions lidar = options.lidar;
  lidar.range_noise_sigma_m = 0.0;
  if (absl::Status s = ValidateLidarOptions(lidar); !s.ok()) return s;
  if (options.noise_sigmas_m.empty()) return absl::InvalidArgumentError("--noise-m: no level");
  for (double sigma : options.noise_sigmas_m) {
    if (!(sigma >= 0.0 && sigma <= 1.0)) {
      return absl::InvalidArgumentError(absl::StrCat("--noise-m: ", sigma, " m is not in [0, 1]"));
    }
  }
  if (options.pair_gaps_m.empty()) return absl::InvalidArgumentError("--pair-gaps: no gap");
  for (double gap : options.pair_gaps_m) {
    if (!(gap > 0.0)) {
      return absl::InvalidArgumentError(absl::StrCat("--pair-gaps: ", gap, " m is not > 0"));
    }
  }
  if (options.pairs < 1) {
    return absl::InvalidArgumentError(absl::StrCat("--pairs: ", options.pairs, " (>= 1)"));
  }
  if (options.movers < 0) {
    return absl::InvalidArgumentError(absl::StrCat("--movers: ", options.movers, " (>= 0)"));
  }
  if (options.threads < 1) {
    return absl::InvalidArgumentError(absl::StrCat("--threads: ", options.threads, " (>= 1)"));
  }
  return absl::OkStatus();
}

absl::StatusOr<LidarProtocolSummary> WriteLidarProtocol(
    const LidarScene& scene, const std::string& name, const std::string& out_dir,
    const LidarProtocolOptions& options, const std::function<void(const std::string&)>& progress) {
  if (absl::Status s = ValidateLidarProtocolOptions(options); !s.ok()) return s;
  LidarOptions lidar = options.lidar;
  lidar.range_noise_sigma_m = 0.0;
  const std::vector<Matrix4>& bases = scene.drive.base_to_world;
  if (bases.size() < 2) return absl::FailedPreconditionError("the drive has fewer than 2 frames");
  const std::vector<double> travelled = TravelledDistances(scene.drive);
  absl::StatusOr<std::vector<FramePair>> pairs =
      SelectFramePairs(travelled, options.pair_gaps_m, options.pairs);
  if (!pairs.ok()) return pairs.status();
  std::set<int> frames;
  for (const FramePair& p : *pairs) frames.insert({p.source, p.target});

  absl::StatusOr<std::unique_ptr<RayCaster>> caster = RayCaster::Build(scene.mesh);
  if (!caster.ok()) return caster.status();
  const double ego_speed = travelled.back() / ((bases.size() - 1) * scene.drive.frame_period_s);
  const std::vector<Mover> movers =
      PlaceMovers(scene.mover_lanes, options.movers, travelled.back(), ego_speed, options.seed);

  const std::string scene_dir = absl::StrCat(out_dir, "/", name);
  for (double sigma : options.noise_sigmas_m) {
    const std::string dir = absl::StrCat(scene_dir, "/", NoiseTag(sigma));
    std::error_code error;
    std::filesystem::create_directories(dir, error);
    if (error) return absl::UnavailableError(absl::StrCat("cannot create '", dir, "'"));
  }

  LidarProtocolSummary summary;
  summary.drive_length_m = travelled.back();
  summary.frames = static_cast<int>(bases.size());
  summary.min_points = static_cast<std::size_t>(-1);
  std::vector<Matrix4> sensor_to_world(bases.size());
  std::string poses = "frame,travelled_m,sensor_to_world,points\n";
  for (int frame : frames) {
    sensor_to_world[frame] = SensorPose(bases[frame], lidar.sensor_height_m);
    const TriangleMesh moving = MoversAt(movers, scene.mover_lanes, scene.drive, travelled, frame);
    std::unique_ptr<RayCaster> moving_caster;
    std::vector<const RayCaster*> world = {caster->get()};
    if (!moving.triangles.empty()) {
      absl::StatusOr<std::unique_ptr<RayCaster>> built = RayCaster::Build(moving);
      if (!built.ok()) return built.status();
      moving_caster = *std::move(built);
      world.push_back(moving_caster.get());
    }
    const PointCloud clean =
        RenderLidarScan(world, sensor_to_world[frame], lidar,
                        SubSeed(options.seed, 0x5343414EULL + frame), options.threads);
    if (clean.empty()) {
      return absl::FailedPreconditionError(
          absl::StrCat("frame ", frame, " of '", name, "': no beam hit anything"));
    }
    summary.scans += 1;
    summary.min_points = std::min(summary.min_points, clean.size());
    summary.max_points = std::max(summary.max_points, clean.size());
    summary.mean_points += static_cast<double>(clean.size());
    for (std::size_t level = 0; level < options.noise_sigmas_m.size(); ++level) {
      const double sigma = options.noise_sigmas_m[level];
      PointCloud noisy = AddRangeNoise(
          clean, sigma, SubSeed(SubSeed(options.seed, 0x4E4F495345ULL + level), frame));
      noisy.viewpoint.reset();  // PLY cannot hold it; the sensor is at the origin anyway
      const std::string path = absl::StrCat(scene_dir, "/", NoiseTag(sigma), "/", ScanFile(frame));
      if (absl::Status s = WritePointCloud(noisy, path); !s.ok()) return s;
      if (progress) progress(path);
    }
    absl::StrAppend(&poses, frame, ",", absl::StrFormat("%.6f", travelled[frame]), ",",
                    CsvField(FormatTransform(sensor_to_world[frame])), ",", clean.size(), "\n");
  }
  summary.mean_points /= summary.scans;
  if (absl::Status s = WriteText(scene_dir + "/poses.csv", poses); !s.ok()) return s;

  for (double sigma : options.noise_sigmas_m) {
    const std::string dir = absl::StrCat(scene_dir, "/", NoiseTag(sigma));
    std::string rows, rows_identity;
    for (const FramePair& p : *pairs) {
      // Source points in the source sensor's frame -> world -> the target sensor's frame.
      const Matrix4 gt = sensor_to_world[p.target].inverse() * sensor_to_world[p.source];
      const double rotation_deg =
          Eigen::AngleAxisd(Eigen::Matrix3d(gt.topLeftCorner<3, 3>())).angle() * 180.0 /
          std::numbers::pi;
      const std::string id =
          absl::StrFormat("%s_%s_%06d_%06d", name, NoiseTag(sigma), p.source, p.target);
      const std::string head = absl::StrCat(CsvField(id), ",", ScanFile(p.source), ",",
                                            ScanFile(p.target), ",", CsvField(FormatTransform(gt)));
      const std::string tail =
          absl::StrFormat("%.6f,%.6f,%s,%g,%d,%d\n", gt.topRightCorner<3, 1>().norm(), rotation_deg,
                          CsvField(name), sigma, p.source, p.target);
      absl::StrAppend(&rows, head, ",", tail);
      absl::StrAppend(&rows_identity, head, ",", CsvField(FormatTransform(Matrix4::Identity())),
                      ",", tail);
    }
    const std::string columns =
        "distance_m,rotation_deg,scene,noise_sigma_m,source_frame,"
        "target_frame\n";
    if (absl::Status s = WriteText(dir + "/pairs.csv", "id,source,target,gt," + columns + rows);
        !s.ok()) {
      return s;
    }
    if (absl::Status s = WriteText(dir + "/pairs_identity.csv",
                                   "id,source,target,gt,init," + columns + rows_identity);
        !s.ok()) {
      return s;
    }
    summary.manifests.push_back(dir + "/pairs.csv");
  }
  summary.pairs = static_cast<int>(pairs->size());
  return summary;
}

}  // namespace mlsreg::scan
