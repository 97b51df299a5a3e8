#include "scan/virtual_scanner.h"

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/io/intrinsics_sidecar.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"

namespace mlsreg::scan {
namespace {

double Radians(double deg) { return deg * std::numbers::pi / 180.0; }

absl::Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  return absl::OkStatus();
}

// Portable float map (PFM, grayscale, little-endian): the depth image, bottom row first.
std::string SerializePfm(const std::vector<float>& depth, int width, int height) {
  std::string out = absl::StrFormat("Pf\n%d %d\n-1.0\n", width, height);
  out.reserve(out.size() + depth.size() * sizeof(float));
  for (int v = height - 1; v >= 0; --v) {
    out.append(reinterpret_cast<const char*>(&depth[static_cast<std::size_t>(v) * width]),
               sizeof(float) * width);
  }
  return out;
}

std::string NoiseTag(double sigma_d) { return absl::StrFormat("sigma%g", sigma_d); }

}  // namespace

PinholeIntrinsics MakeIntrinsics(const CameraOptions& options) {
  PinholeIntrinsics k;
  k.width = options.width;
  k.height = options.height;
  k.fy = 0.5 * options.height / std::tan(0.5 * Radians(options.fov_y_deg));
  k.fx = k.fy;
  k.cx = 0.5 * (options.width - 1);  // pixel centres sit at integer coordinates
  k.cy = 0.5 * (options.height - 1);
  return k;
}

double FramingDistance(double radius, const CameraOptions& options) {
  const PinholeIntrinsics k = MakeIntrinsics(options);
  const double half_angle = std::atan(0.5 * std::min(k.width, k.height) / k.fy);
  return options.margin * radius / std::sin(half_angle);
}

Camera CircleCamera(const Vec3& center, double distance, double angle_deg,
                    const CameraOptions& options) {
  const double a = Radians(angle_deg);
  const Vec3 position = center + distance * Vec3(std::sin(a), 0.0, std::cos(a));
  const Vec3 forward = (center - position).normalized();
  const Vec3 down(0.0, -1.0, 0.0);
  const Vec3 right = down.cross(forward).normalized();
  Camera camera;
  camera.intrinsics = MakeIntrinsics(options);
  camera.camera_to_world.topLeftCorner<3, 3>().col(0) = right;
  camera.camera_to_world.topLeftCorner<3, 3>().col(1) = forward.cross(right);
  camera.camera_to_world.topLeftCorner<3, 3>().col(2) = forward;
  camera.camera_to_world.topRightCorner<3, 1>() = position;
  return camera;
}

Scan RenderScan(const RayCaster& caster, const Camera& camera) {
  const PinholeIntrinsics& k = camera.intrinsics;
  const Eigen::Matrix3d rotation = camera.camera_to_world.topLeftCorner<3, 3>();
  const Vec3 origin = camera.camera_to_world.topRightCorner<3, 1>();
  Scan scan;
  scan.cloud.intrinsics = k;
  scan.cloud.viewpoint = Vec3::Zero();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Vec3 ray_camera = Vec3((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0).normalized();
      const std::optional<RayHit> hit = caster.Cast(origin, rotation * ray_camera);
      if (!hit) continue;
      scan.cloud.points.push_back(hit->distance * ray_camera);
      scan.surface_normals.push_back(rotation.transpose() * hit->normal);
      scan.pixels.push_back(static_cast<std::uint32_t>(v * k.width + u));
    }
  }
  return scan;
}

Scan AddNormalNoise(const Scan& scan, double sigma, std::uint64_t seed) {
  Scan noisy = scan;
  if (sigma <= 0.0) return noisy;
  std::mt19937_64 random(seed);
  std::normal_distribution<double> gaussian(0.0, sigma);
  for (std::size_t i = 0; i < noisy.cloud.points.size(); ++i) {
    noisy.cloud.points[i] += gaussian(random) * noisy.surface_normals[i];
  }
  return noisy;
}

std::vector<float> DepthImage(const Scan& scan) {
  const PinholeIntrinsics& k = *scan.cloud.intrinsics;
  std::vector<float> depth(static_cast<std::size_t>(k.width) * k.height, 0.0f);
  for (std::size_t i = 0; i < scan.pixels.size(); ++i) {
    depth[scan.pixels[i]] = static_cast<float>(scan.cloud.points[i].z());
  }
  return depth;
}

absl::StatusOr<ProtocolSummary> WriteScanProtocol(
    const TriangleMesh& mesh, const std::string& name, const std::string& out_dir,
    const ProtocolOptions& options, const std::function<void(const std::string&)>& progress) {
  if (options.views < 2) return absl::InvalidArgumentError("views: at least 2 are needed");
  for (double sigma : options.noise_sigmas_d) {
    if (!(sigma >= 0.0)) return absl::InvalidArgumentError("noise: sigmas must be >= 0");
  }
  absl::StatusOr<std::unique_ptr<RayCaster>> caster = RayCaster::Build(mesh);
  if (!caster.ok()) return caster.status();
  const Vec3 center = mesh.SurfaceCentroid();
  const double distance = FramingDistance(mesh.BoundingRadius(center), options.camera);

  // Render the noise-free views first: d, the unit of the noise, is their mean.
  std::vector<Camera> cameras;
  std::vector<double> angles;
  std::vector<Scan> scans;
  ProtocolSummary summary;
  for (int view = 0; view < options.views; ++view) {
    angles.push_back(360.0 * view / options.views);
    cameras.push_back(CircleCamera(center, distance, angles.back(), options.camera));
    scans.push_back(RenderScan(**caster, cameras.back()));
    if (scans.back().cloud.size() < 2) {
      return absl::FailedPreconditionError(
          absl::StrCat("view ", view, " of '", name, "' hit the mesh with fewer than 2 rays"));
    }
    summary.points += scans.back().cloud.size();
    summary.sampling_distance +=
        SamplingDistance(scans.back().cloud.points, KdTree(scans.back().cloud.points));
  }
  summary.sampling_distance /= options.views;
  const double d = summary.sampling_distance;

  for (std::size_t level = 0; level < options.noise_sigmas_d.size(); ++level) {
    const double sigma_d = options.noise_sigmas_d[level];
    const std::string dir = absl::StrCat(out_dir, "/", name, "/", NoiseTag(sigma_d));
    std::error_code error;
    std::filesystem::create_directories(dir, error);
    if (error) return absl::UnavailableError(absl::StrCat("cannot create '", dir, "'"));
    std::vector<std::string> files;
    std::string poses = "view,angle_deg,camera_to_world,sampling_distance,points\n";
    for (int view = 0; view < options.views; ++view) {
      const std::uint64_t seed = options.seed * 1000003ULL + level * 1009ULL + view;
      const Scan noisy = AddNormalNoise(scans[view], sigma_d * d, seed);
      files.push_back(absl::StrFormat("view_%03.0f.ply", angles[view]));
      const std::string path = dir + "/" + files.back();
      PointCloud cloud = noisy.cloud;
      cloud.viewpoint.reset();  // PLY cannot hold it; the camera sits at the origin anyway
      if (absl::Status s = WritePointCloud(cloud, path); !s.ok()) return s;
      if (absl::Status s = WriteText(path + ".intrinsics", FormatIntrinsics(*cloud.intrinsics));
          !s.ok()) {
        return s;
      }
      const std::string depth_path = absl::StrFormat("%s/view_%03.0f.depth.pfm", dir, angles[view]);
      if (absl::Status s = WriteText(
              depth_path,
              SerializePfm(DepthImage(noisy), cloud.intrinsics->width, cloud.intrinsics->height));
          !s.ok()) {
        return s;
      }
      absl::StrAppend(&poses, view, ",", angles[view], ",",
                      CsvField(FormatTransform(cameras[view].camera_to_world)), ",",
                      absl::StrFormat("%.9g", d), ",", cloud.size(), "\n");
      if (progress) progress(path);
    }
    if (absl::Status s = WriteText(dir + "/poses.csv", poses); !s.ok()) return s;

    std::string pairs = "id,source,target,gt,init,mesh,noise_sigma_d,source_deg,target_deg\n";
    for (int view = 0; view < options.views; ++view) {
      const int source = (view + 1) % options.views;
      // Source points in camera `source` -> world -> camera `view`.
      const Matrix4 gt = cameras[view].camera_to_world.inverse() * cameras[source].camera_to_world;
      absl::StrAppend(&pairs,
                      absl::StrFormat("%s_%s_%03.0f_%03.0f", name, NoiseTag(sigma_d),
                                      angles[source], angles[view]),
                      ",", files[source], ",", files[view], ",", CsvField(FormatTransform(gt)), ",",
                      CsvField(FormatTransform(Matrix4::Identity())), ",", CsvField(name), ",",
                      absl::StrFormat("%g", sigma_d), ",", angles[source], ",", angles[view], "\n");
    }
    const std::string manifest = dir + "/pairs.csv";
    if (absl::Status s = WriteText(manifest, pairs); !s.ok()) return s;
    summary.manifests.push_back(manifest);
  }
  return summary;
}

}  // namespace mlsreg::scan
