// mlsreg-scan: the virtual scanner. Scans triangle meshes under the paper's synthetic protocol and
// writes organised scans, depth images, intrinsics, poses and `mlsreg eval` manifests.
//
//   mlsreg-scan --mesh bunny=bun_zipper.ply --mesh cow.off --out scans/
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_format.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/io/mesh_io.h"
#include "scan/virtual_scanner.h"

namespace {

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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mlsreg-scan: virtual scans of triangle meshes (OFF, OBJ, PLY) for evaluation"};
  std::vector<std::string> meshes;
  std::string out = "scans";
  mlsreg::scan::ProtocolOptions options;
  app.add_option("--mesh", meshes, "mesh file, or name=file (repeatable)")->required();
  app.add_option("--out", out, "output folder")->capture_default_str();
  app.add_option("--views", options.views, "viewpoints on the circle")->capture_default_str();
  app.add_option("--noise", options.noise_sigmas_d,
                 "noise levels: sigma along the normal, in units of d (comma separated)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--width", options.camera.width, "image width (pixels)")->capture_default_str();
  app.add_option("--height", options.camera.height, "image height (pixels)")->capture_default_str();
  app.add_option("--fov", options.camera.fov_y_deg, "vertical field of view (degrees)")
      ->capture_default_str();
  app.add_option("--seed", options.seed, "noise seed")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  if (options.camera.width < 2 || options.camera.height < 2 || !(options.camera.fov_y_deg > 0.0) ||
      !(options.camera.fov_y_deg < 180.0)) {
    std::fprintf(stderr, "mlsreg-scan: --width/--height must be >= 2 and --fov in (0, 180)\n");
    return 2;
  }

  for (const std::string& spec : meshes) {
    const auto [name, path] = NameAndPath(spec);
    absl::StatusOr<mlsreg::TriangleMesh> mesh = mlsreg::ReadTriangleMesh(path);
    if (!mesh.ok()) {
      std::fprintf(stderr, "mlsreg-scan: %s\n", std::string(mesh.status().message()).c_str());
      return mesh.status().code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
    }
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
      return 1;
    }
    std::printf("%s: %zu vertices, %zu triangles; %d views, %.0f points per view, d = %.6g\n",
                name.c_str(), mesh->vertices.size(), mesh->triangles.size(), options.views,
                static_cast<double>(summary->points) / options.views, summary->sampling_distance);
    for (const std::string& manifest : summary->manifests) std::printf("  %s\n", manifest.c_str());
  }
  return 0;
}
