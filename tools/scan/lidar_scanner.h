// LidarScanner: a 360-degree multi-beam spinning LiDAR (like a Velodyne HDL-64E on a car). Each
// beam sweeps a cone of constant elevation; one full turn at a fixed azimuth step is one scan.
// Points are returned in the SENSOR frame (x forward, y left, z up; the sensor at the origin),
// ring by ring from the highest beam down, each ring by azimuth from -180 degrees (behind)
// counter-clockwise (seen from above). Returns closer than the minimum range (the car itself) or
// beyond the maximum range are dropped, as are rays that hit nothing. Range noise is Gaussian
// along the ray. The car carrying the sensor shadows the lowest beams (ego_body): on a KITTI
// scan, the beams below about -17 degrees lose the rear, below about -22 degrees the front.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "scan/ray_caster.h"

namespace mlsreg::scan {

struct LidarOptions {
  int beams = 64;
  // Elevations of the first (highest) and last beam; the beams are evenly spaced between them.
  double top_elevation_deg = 2.0;
  double bottom_elevation_deg = -24.8;
  // When not empty, the beams' elevations themselves (one per beam, top first; overrides the
  // three above). HDL64EElevationsDeg() gives the real sensor's uneven layout.
  std::vector<double> elevations_deg;
  double azimuth_step_deg = 0.2;  // 0.1-0.4; rounded so that a whole number of steps make 360
  double min_range_m = 2.5;
  double max_range_m = 80.0;
  double range_noise_sigma_m = 0.0;  // Gaussian, along the ray
  double dropout_probability = 0.0;  // of losing a return at random (dark or shiny surfaces)
  // Where the protocol puts the sensor above the ground the car drives on (the drive's base).
  double sensor_height_m = 1.73;
  // The carrying car's roof, below the sensor: an ellipse (semi-axes along x and y) centred at
  // ego_body_center in the sensor frame, its z the roof's height. A ray that reaches the roof's
  // level inside the ellipse ends on the car and returns nothing. The default (1.25 m ahead to
  // 1.65 m behind, 0.9 m to either side, 0.5 m below the sensor) shadows the low beams about as
  // on KITTI's HDL-64E: rear below -17 degrees, front below -22.
  bool ego_body = true;
  Vec3 ego_body_center = Vec3(-0.2, 0.0, -0.5);
  double ego_body_semi_x_m = 1.45, ego_body_semi_y_m = 0.9;
};

// InvalidArgument naming the CLI flag of the first bad value: --beams (1-256), --azimuth-step
// (0.1-0.4), --min-range (> 0), --max-range (above the minimum, at most 1000 m), --noise-m
// (0-1 m), --dropout ([0, 1)), --sensor-height (0-100 m); elevations in (-90, 90) and strictly
// decreasing; the ego body's roof below the sensor.
absl::Status ValidateLidarOptions(const LidarOptions& options);

// The beams' elevations (degrees, top first).
std::vector<double> BeamElevationsDeg(const LidarOptions& options);
// The HDL-64E's 64 elevations: 32 beams from +2.0 to -8.33 degrees (1/3 degree apart) above 32
// from -8.83 to -24.33 (1/2 degree apart).
std::vector<double> HDL64EElevationsDeg();
// The number of azimuth steps in one turn (360 / step, rounded).
int AzimuthSteps(const LidarOptions& options);

// One turn of the sensor at `sensor_to_world` against the first hit among `world` (e.g. the
// static scene and the moving objects of this frame), noise and dropouts drawn from `seed`. The
// cloud's viewpoint is (0, 0, 0). The options must pass ValidateLidarOptions. Deterministic: the
// same inputs give the same points whatever the thread count.
PointCloud RenderLidarScan(std::span<const RayCaster* const> world, const Matrix4& sensor_to_world,
                           const LidarOptions& options, std::uint64_t seed, int threads = 1);
PointCloud RenderLidarScan(const RayCaster& caster, const Matrix4& sensor_to_world,
                           const LidarOptions& options, std::uint64_t seed, int threads = 1);

// `cloud` (in its sensor's frame, the sensor at the origin) with every point moved along its ray
// by N(0, sigma) metres, seeded; sigma = 0 returns it unchanged.
PointCloud AddRangeNoise(const PointCloud& cloud, double sigma_m, std::uint64_t seed);

}  // namespace mlsreg::scan
