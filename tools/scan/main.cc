// mlsreg-scan: the virtual scanner. Scans triangle meshes under the paper's synthetic protocol and
// writes organised scans, depth images, intrinsics, poses and `mlsreg eval` manifests; with
// --lidar, drives a spinning multi-beam LiDAR through procedural streets (or a user's mesh) and
// writes KITTI-like scan pairs.
//
//   mlsreg-scan --mesh bunny=bun_zipper.ply --mesh cow.off --out scans/
//   mlsreg-scan --lidar --scene street --scenes 3 --scene-seed 1 --out lidar/
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/io/mesh_io.h"
#include "scan/lidar_protocol.h"
#include "scan/virtual_scanner.h"

namespace {

constexpr int kExitFailed = 1;
constexpr int kExitBadInput = 2;

// "name=path" or just "path" (the name is then the file name without its extension).
std::pair<std::string, std::string> NameAndPath(const std::string& spec) {
  const std::size_t eq = spec.find('=');
  if (eq != std::string::npos) return {spec.substr(0, eq), spec.substr(eq + 1)};
  const std::size_t slash = spec.find_last_of('/');
  std::string name = spec.substr(slash == std::string::npos ? 0 : slash + 1);
  const std::size_t dot = name.find_last_of('.');
  if (dot != std::string::npos && dot > 0) name.resize(dot);
  return {name, spec};
}

int Fail(const absl::Status& status, const std::string& context = "") {
  std::fprintf(stderr, "mlsreg-scan: %s%s\n", context.empty() ? "" : (context + ": ").c_str(),
               std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitBadInput : kExitFailed;
}

// The scene as Wavefront OBJ, for looking at it.
absl::Status WriteObj(const mlsreg::TriangleMesh& mesh, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  for (const mlsreg::Vec3& v : mesh.vertices) {
    out << absl::StrFormat("v %.4f %.4f %.4f\n", v.x(), v.y(), v.z());
  }
  for (const auto& t : mesh.triangles) {
    out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  }
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  return absl::OkStatus();
}

int RunMeshProtocol(const std::vector<std::string>& meshes, const std::string& out,
                    const mlsreg::scan::ProtocolOptions& options) {
  if (options.camera.width < 2 || options.camera.height < 2 || !(options.camera.fov_y_deg > 0.0) ||
      !(options.camera.fov_y_deg < 180.0)) {
    std::fprintf(stderr, "mlsreg-scan: --width/--height must be >= 2 and --fov in (0, 180)\n");
    return kExitBadInput;
  }
  for (const std::string& spec : meshes) {
    const auto [name, path] = NameAndPath(spec);
    absl::StatusOr<mlsreg::TriangleMesh> mesh = mlsreg::ReadTriangleMesh(path);
    if (!mesh.ok()) return Fail(mesh.status());
    int done = 0;
    const int total = options.views * static_cast<int>(options.noise_sigmas_d.size());
    const bool terminal = isatty(fileno(stderr));
    auto summary =
        mlsreg::scan::WriteScanProtocol(*mesh, name, out, options, [&](const std::string& file) {
          if (terminal)
            std::fprintf(stderr, "\r%s: %d/%d %s", name.c_str(), ++done, total, file.c_str());
        });
    if (terminal) std::fprintf(stderr, "\n");
    if (!summary.ok()) {
      std::fprintf(stderr, "mlsreg-scan: %s: %s\n", name.c_str(),
                   std::string(summary.status().message()).c_str());
      return kExitFailed;
    }
    std::printf("%s: %zu vertices, %zu triangles; %d views, %.0f points per view, d = %.6g\n",
                name.c_str(), mesh->vertices.size(), mesh->triangles.size(), options.views,
                static_cast<double>(summary->points) / options.views, summary->sampling_distance);
    for (const std::string& manifest : summary->manifests) std::printf("  %s\n", manifest.c_str());
  }
  return 0;
}

struct LidarRun {
  std::string out;
  bool save_scene = false;
  mlsreg::scan::LidarProtocolOptions protocol;
  mlsreg::scan::DriveOptions drive;
};

int WriteLidarScene(const mlsreg::scan::LidarScene& scene, const std::string& name,
                    const std::string& description, const LidarRun& run) {
  const auto start = std::chrono::steady_clock::now();
  const bool terminal = isatty(fileno(stderr));
  int done = 0;
  auto summary = mlsreg::scan::WriteLidarProtocol(
      scene, name, run.out, run.protocol, [&](const std::string& file) {
        if (terminal) std::fprintf(stderr, "\r%s: %d %s", name.c_str(), ++done, file.c_str());
      });
  if (terminal) std::fprintf(stderr, "\n");
  if (!summary.ok()) return Fail(summary.status(), name);
  if (run.save_scene) {
    if (absl::Status s = WriteObj(scene.mesh, absl::StrCat(run.out, "/", name, "/scene.obj"));
        !s.ok()) {
      return Fail(s, name);
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "%s: %s, %zu triangles; drive %.1f m in %d frames; %d scans of %.0f points (%zu-%zu), "
      "%d pairs; %.1f s\n",
      name.c_str(), description.c_str(), scene.mesh.triangles.size(), summary->drive_length_m,
      summary->frames, summary->scans, summary->mean_points, summary->min_points,
      summary->max_points, summary->pairs, seconds);
  for (const std::string& manifest : summary->manifests) std::printf("  %s\n", manifest.c_str());
  return 0;
}

int RunLidar(const std::vector<std::string>& meshes, const std::string& kind_name, int scenes,
             std::uint64_t scene_seed, const LidarRun& run) {
  if (absl::Status s = mlsreg::scan::ValidateDriveOptions(run.drive); !s.ok()) return Fail(s);
  if (absl::Status s = mlsreg::scan::ValidateLidarProtocolOptions(run.protocol); !s.ok()) {
    return Fail(s);
  }
  if (!meshes.empty()) {
    for (const std::string& spec : meshes) {
      const auto [name, path] = NameAndPath(spec);
      absl::StatusOr<mlsreg::TriangleMesh> mesh = mlsreg::ReadTriangleMesh(path);
      if (!mesh.ok()) return Fail(mesh.status());
      mlsreg::scan::DriveOptions drive = run.drive;
      drive.seed = scene_seed;
      absl::StatusOr<mlsreg::scan::LidarScene> scene =
          mlsreg::scan::MakeMeshLidarScene(*std::move(mesh), drive);
      if (!scene.ok()) return Fail(scene.status(), name);
      if (int code = WriteLidarScene(*scene, name, "mesh " + path, run); code != 0) return code;
    }
    return 0;
  }
  absl::StatusOr<mlsreg::scan::StreetKind> kind = mlsreg::scan::ParseStreetKind(kind_name);
  if (!kind.ok()) return Fail(kind.status());
  if (scenes < 1) return Fail(absl::InvalidArgumentError("--scenes: must be >= 1"));
  for (int k = 0; k < scenes; ++k) {
    mlsreg::scan::StreetSceneOptions options;
    options.kind = *kind;
    options.seed = scene_seed + static_cast<std::uint64_t>(k);
    mlsreg::scan::DriveOptions drive = run.drive;
    drive.seed = options.seed;
    const mlsreg::scan::StreetLayout layout = mlsreg::scan::MakeStreetLayout(options);
    const mlsreg::scan::LidarScene scene = mlsreg::scan::MakeStreetLidarScene(options, drive);
    const std::string name = absl::StrCat(mlsreg::scan::StreetKindName(*kind), "_s", options.seed);
    const std::string description = absl::StrFormat(
        "%.0f m %s%s", layout.length_m, mlsreg::scan::StreetKindName(*kind),
        layout.bend_angle_rad != 0.0
            ? absl::StrFormat(" (bend %.0f deg)", layout.bend_angle_rad * 180.0 / 3.14159265)
            : std::string());
    if (int code = WriteLidarScene(scene, name, description, run); code != 0) return code;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mlsreg-scan: virtual scans of triangle meshes (OFF, OBJ, PLY) for evaluation; with "
      "--lidar, a spinning LiDAR driven through procedural streets"};
  std::vector<std::string> meshes;
  std::string out = "scans";
  mlsreg::scan::ProtocolOptions options;
  app.add_option("--mesh", meshes, "mesh file, or name=file (repeatable)");
  app.add_option("--out", out, "output folder")->capture_default_str();
  auto* seed = app.add_option("--seed", options.seed, "noise seed (--lidar: also movers)")
                   ->capture_default_str();
  // The pinhole protocol's flags.
  const std::vector<CLI::Option*> mesh_only = {
      app.add_option("--views", options.views, "viewpoints on the circle")->capture_default_str(),
      app.add_option("--noise", options.noise_sigmas_d,
                     "noise levels: sigma along the normal, in units of d (comma separated)")
          ->delimiter(',')
          ->capture_default_str(),
      app.add_option("--width", options.camera.width, "image width (pixels)")
          ->capture_default_str(),
      app.add_option("--height", options.camera.height, "image height (pixels)")
          ->capture_default_str(),
      app.add_option("--fov", options.camera.fov_y_deg, "vertical field of view (degrees)")
          ->capture_default_str()};

  // The LiDAR mode's flags.
  bool lidar = false, no_ego_body = false;
  std::string scene_kind = "street", beam_layout = "uniform";
  int scenes = 1;
  std::uint64_t scene_seed = 1;
  LidarRun run;
  std::vector<double> steps = {run.drive.min_step_m, run.drive.max_step_m};
  mlsreg::scan::LidarOptions& l = run.protocol.lidar;
  run.protocol.threads = mlsreg::HardwareThreads();
  app.add_flag("--lidar", lidar,
               "spinning LiDAR along a drive: through --scene streets, or straight through each "
               "--mesh (metres, z up)");
  const std::vector<CLI::Option*> lidar_only = {
      app.add_option("--scene", scene_kind, "street, corridor or open_road")->capture_default_str(),
      app.add_option("--scenes", scenes, "how many scenes (seeds --scene-seed, +1, ...)")
          ->capture_default_str(),
      app.add_option("--scene-seed", scene_seed, "seed of the first scene (and its drive)")
          ->capture_default_str(),
      app.add_option("--noise-m", run.protocol.noise_sigmas_m,
                     "range noise levels along the rays, sigma in metres (comma separated)")
          ->delimiter(',')
          ->capture_default_str(),
      app.add_option("--beams", l.beams, "beams (evenly spaced from --top-elevation down)")
          ->capture_default_str(),
      app.add_option("--beam-layout", beam_layout,
                     "uniform (evenly spaced) or hdl64e (the real sensor's 1/3 and 1/2 degree "
                     "blocks; 64 beams)")
          ->capture_default_str(),
      app.add_option("--top-elevation", l.top_elevation_deg, "highest beam (degrees)")
          ->capture_default_str(),
      app.add_option("--bottom-elevation", l.bottom_elevation_deg, "lowest beam (degrees)")
          ->capture_default_str(),
      app.add_option("--azimuth-step", l.azimuth_step_deg, "degrees between shots (0.1-0.4)")
          ->capture_default_str(),
      app.add_option("--min-range", l.min_range_m, "metres; closer returns are dropped")
          ->capture_default_str(),
      app.add_option("--max-range", l.max_range_m, "metres; farther returns are dropped")
          ->capture_default_str(),
      app.add_option("--sensor-height", l.sensor_height_m, "above the road (metres)")
          ->capture_default_str(),
      app.add_option("--dropout", l.dropout_probability, "probability of losing a return")
          ->capture_default_str(),
      app.add_option("--frames", run.drive.frames,
                     "at most this many frames of the drive (0: the whole street)")
          ->capture_default_str(),
      app.add_option("--step-m", steps, "MIN,MAX metres travelled per frame")
          ->delimiter(',')
          ->expected(2)
          ->capture_default_str(),
      app.add_option("--pair-gaps", run.protocol.pair_gaps_m,
                     "travelled metres between a pair's frames, taken in turn (comma separated)")
          ->delimiter(',')
          ->capture_default_str(),
      app.add_option("--pairs", run.protocol.pairs, "pairs per scene")->capture_default_str(),
      app.add_option("--movers", run.protocol.movers,
                     "moving cars and pedestrians along the drive (no ground truth)")
          ->capture_default_str(),
      app.add_option("--threads", run.protocol.threads, "rendering threads")->capture_default_str(),
      app.add_flag("--save-scene", run.save_scene, "also write each scene as scene.obj"),
      app.add_flag("--no-ego-body", no_ego_body,
                   "no shadow of the carrying car on the lowest beams")};
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : kExitBadInput;
  }
  (void)seed;

  if (!lidar) {
    for (const CLI::Option* option : lidar_only) {
      if (option->count() > 0) {
        std::fprintf(stderr, "mlsreg-scan: %s needs --lidar\n", option->get_name().c_str());
        return kExitBadInput;
      }
    }
    if (meshes.empty()) {
      std::fprintf(stderr, "mlsreg-scan: --mesh is required (or --lidar)\n");
      return kExitBadInput;
    }
    return RunMeshProtocol(meshes, out, options);
  }
  for (const CLI::Option* option : mesh_only) {
    if (option->count() > 0) {
      std::fprintf(stderr, "mlsreg-scan: %s is for pinhole scans, not --lidar\n",
                   option->get_name().c_str());
      return kExitBadInput;
    }
  }
  if (!meshes.empty() && (app.count("--scene") + app.count("--scenes") > 0)) {
    std::fprintf(stderr, "mlsreg-scan: --scene/--scenes and --mesh exclude each other\n");
    return kExitBadInput;
  }
  if (beam_layout == "hdl64e") {
    l.elevations_deg = mlsreg::scan::HDL64EElevationsDeg();
  } else if (beam_layout != "uniform") {
    std::fprintf(stderr, "mlsreg-scan: --beam-layout: '%s' is not uniform or hdl64e\n",
                 beam_layout.c_str());
    return kExitBadInput;
  }
  l.ego_body = !no_ego_body;
  run.out = out;
  run.drive.min_step_m = steps[0];
  run.drive.max_step_m = steps[1];
  run.protocol.seed = options.seed;
  return RunLidar(meshes, scene_kind, scenes, scene_seed, run);
}
