// VirtualScanner: renders organised, optionally noisy scans of a triangle mesh from pinhole
// cameras, and the paper's synthetic protocol (section 5.1) on top of it: views uniformly spaced
// on a circle in the xz-plane around the mesh's barycenter, Gaussian noise along the surface
// normal in units of the scans' sampling distance d, and the neighbouring-view pairs with ground
// truth from the camera poses.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/core/triangle_mesh.h"
#include "scan/ray_caster.h"

namespace mlsreg::scan {

// A pinhole camera: x right, y down, looking along +z (the convention of DepthGrid).
struct Camera {
  PinholeIntrinsics intrinsics;
  Matrix4 camera_to_world = Matrix4::Identity();
};

struct CameraOptions {
  int width = 320;
  int height = 240;
  double fov_y_deg = 40.0;  // vertical field of view; pixels are square
  double margin = 1.1;      // the bounding sphere's silhouette fills 1/margin of the shorter side
};

PinholeIntrinsics MakeIntrinsics(const CameraOptions& options);

// The camera at `angle_deg` on the circle of radius `distance` in the xz-plane around `center`
// (angle 0 on the +z side, increasing toward +x), looking at `center` with world +y up.
Camera CircleCamera(const Vec3& center, double distance, double angle_deg,
                    const CameraOptions& options);

// The distance at which a sphere of `radius` fits the view with the options' margin.
double FramingDistance(double radius, const CameraOptions& options);

// One rendered view, in the camera's frame.
struct Scan {
  PointCloud cloud;                   // hit points in row-major pixel order, intrinsics set
  std::vector<Vec3> surface_normals;  // the true normal at each point, facing the camera
  std::vector<std::uint32_t> pixels;  // pixel index (v * width + u) of each point
};

Scan RenderScan(const RayCaster& caster, const Camera& camera);

// A copy of `scan` whose points moved along their true normals by N(0, sigma) (absolute units),
// seeded. sigma = 0 returns the scan unchanged.
Scan AddNormalNoise(const Scan& scan, double sigma, std::uint64_t seed);

// The organised depth image of a scan: z per pixel, 0 where the ray hit nothing.
std::vector<float> DepthImage(const Scan& scan);

struct ProtocolOptions {
  int views = 12;
  std::vector<double> noise_sigmas_d = {0.0, 0.8, 2.0};
  CameraOptions camera;
  std::uint64_t seed = 1;
};

struct ProtocolSummary {
  double sampling_distance = 0.0;      // mean d (paper Eq. 11) of the noise-free views
  std::size_t points = 0;              // over all noise-free views
  std::vector<std::string> manifests;  // one pairs.csv per noise level
};

// Scans `mesh` under the protocol and writes, below `out_dir/name/`:
//   sigma<s>/view_<angle>.ply          the scan in its camera's frame
//   sigma<s>/view_<angle>.ply.intrinsics  its pinhole intrinsics (read by ReadPointCloud)
//   sigma<s>/view_<angle>.depth.pfm    its organised depth image (z, 0 for no hit)
//   sigma<s>/poses.csv                 view, angle and camera-to-world pose of each view
//   sigma<s>/pairs.csv                 the neighbouring-view pairs (source = view i+1, target =
//                                      view i), gt from the poses, init = identity (the scanner's
//                                      motion is the only perturbation), and columns mesh, noise
// `progress` (may be empty) is told each finished view.
absl::StatusOr<ProtocolSummary> WriteScanProtocol(
    const TriangleMesh& mesh, const std::string& name, const std::string& out_dir,
    const ProtocolOptions& options, const std::function<void(const std::string&)>& progress = {});

}  // namespace mlsreg::scan
