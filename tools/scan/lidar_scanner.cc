#include "scan/lidar_scanner.h"

#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "mlsreg/core/parallel_for.h"
#include "scan/seeded_random.h"

namespace mlsreg::scan {
namespace {

double Radians(double deg) { return deg * std::numbers::pi / 180.0; }

// Whether `ray` (unit, from the sensor) ends on the carrying car before `distance`.
bool HitsEgoBody(const Vec3& ray, double distance, const LidarOptions& o) {
  const double depth = o.ego_body_center.z();
  if (ray.z() >= 0.0) return false;
  const double t = depth / ray.z();  // where the ray is at the roof's level
  if (t >= distance) return false;
  const double dx = (t * ray.x() - o.ego_body_center.x()) / o.ego_body_semi_x_m;
  const double dy = (t * ray.y() - o.ego_body_center.y()) / o.ego_body_semi_y_m;
  return dx * dx + dy * dy < 1.0;
}

}  // namespace

absl::Status ValidateLidarOptions(const LidarOptions& o) {
  if (o.elevations_deg.empty() && !(o.beams >= 1 && o.beams <= 256)) {
    return absl::InvalidArgumentError(absl::StrCat("--beams: ", o.beams, " is not in 1-256"));
  }
  if (o.elevations_deg.size() > 256) {
    return absl::InvalidArgumentError("elevations: more than 256 beams");
  }
  if (!(o.azimuth_step_deg >= 0.1 - 1e-12 && o.azimuth_step_deg <= 0.4 + 1e-12)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--azimuth-step: ", o.azimuth_step_deg, " degrees is not in 0.1-0.4"));
  }
  if (!(o.min_range_m > 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--min-range: ", o.min_range_m, " m must be > 0"));
  }
  if (!(o.max_range_m > o.min_range_m && o.max_range_m <= 1000.0)) {
    return absl::InvalidArgumentError(absl::StrCat("--max-range: ", o.max_range_m,
                                                   " m is not in (--min-range = ", o.min_range_m,
                                                   " m, 1000 m]"));
  }
  if (!(o.range_noise_sigma_m >= 0.0 && o.range_noise_sigma_m <= 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--noise-m: ", o.range_noise_sigma_m, " m is not in [0, 1]"));
  }
  if (!(o.dropout_probability >= 0.0 && o.dropout_probability < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--dropout: ", o.dropout_probability, " is not in [0, 1)"));
  }
  if (!(o.sensor_height_m >= 0.0 && o.sensor_height_m <= 100.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--sensor-height: ", o.sensor_height_m, " m is not in [0, 100]"));
  }
  if (o.ego_body && !(o.ego_body_center.z() < 0.0 && o.ego_body_semi_x_m > 0.0 &&
                      o.ego_body_semi_y_m > 0.0 && o.ego_body_center.allFinite())) {
    return absl::InvalidArgumentError(
        "ego body: the roof must be below the sensor with positive semi-axes");
  }
  const std::vector<double> elevations = BeamElevationsDeg(o);
  for (std::size_t k = 0; k < elevations.size(); ++k) {
    if (!(elevations[k] > -90.0 && elevations[k] < 90.0) ||
        (k > 0 && !(elevations[k] < elevations[k - 1]))) {
      return absl::InvalidArgumentError(
          absl::StrCat("elevations: beam ", k, " at ", elevations[k],
                       " degrees is not in (-90, 90) below the beam before it"));
    }
  }
  return absl::OkStatus();
}

std::vector<double> BeamElevationsDeg(const LidarOptions& options) {
  if (!options.elevations_deg.empty()) return options.elevations_deg;
  std::vector<double> elevations;
  for (int k = 0; k < options.beams; ++k) {
    elevations.push_back(options.beams == 1
                             ? options.top_elevation_deg
                             : options.top_elevation_deg +
                                   (options.bottom_elevation_deg - options.top_elevation_deg) * k /
                                       (options.beams - 1));
  }
  return elevations;
}

std::vector<double> HDL64EElevationsDeg() {
  std::vector<double> elevations;
  for (int k = 0; k < 32; ++k) elevations.push_back(2.0 - k / 3.0);
  for (int k = 0; k < 32; ++k) elevations.push_back(-8.83 - 0.5 * k);
  return elevations;
}

int AzimuthSteps(const LidarOptions& options) {
  return std::max(1, static_cast<int>(std::lround(360.0 / options.azimuth_step_deg)));
}

PointCloud RenderLidarScan(std::span<const RayCaster* const> world, const Matrix4& sensor_to_world,
                           const LidarOptions& options, std::uint64_t seed, int threads) {
  const std::vector<double> elevations = BeamElevationsDeg(options);
  const int steps = AzimuthSteps(options);
  std::vector<double> cos_azimuth(steps), sin_azimuth(steps);
  for (int c = 0; c < steps; ++c) {
    const double azimuth = -std::numbers::pi + 2.0 * std::numbers::pi * c / steps;
    cos_azimuth[c] = std::cos(azimuth);
    sin_azimuth[c] = std::sin(azimuth);
  }
  const Eigen::Matrix3d rotation = sensor_to_world.topLeftCorner<3, 3>();
  const Vec3 origin = sensor_to_world.topRightCorner<3, 1>();
  std::vector<std::vector<Vec3>> rings(elevations.size());
  ParallelFor(
      elevations.size(), threads,
      [&](std::size_t begin, std::size_t end, int) {
        for (std::size_t ring = begin; ring < end; ++ring) {
          SeededRandom dropouts(SubSeed(seed, ring));
          const double e = Radians(elevations[ring]);
          const double horizontal = std::cos(e), vertical = std::sin(e);
          std::vector<Vec3>& points = rings[ring];
          points.reserve(steps);
          for (int c = 0; c < steps; ++c) {
            const Vec3 ray(horizontal * cos_azimuth[c], horizontal * sin_azimuth[c], vertical);
            const Vec3 direction = rotation * ray;
            double nearest = options.max_range_m;
            bool hit_any = false;
            for (const RayCaster* caster : world) {
              const std::optional<RayHit> hit = caster->Cast(origin, direction);
              if (hit && hit->distance <= nearest) {
                nearest = hit->distance;
                hit_any = true;
              }
            }
            if (options.dropout_probability > 0.0 && dropouts.Chance(options.dropout_probability)) {
              continue;
            }
            if (!hit_any || nearest < options.min_range_m) continue;
            if (options.ego_body && HitsEgoBody(ray, nearest, options)) continue;
            points.push_back(nearest * ray);
          }
        }
      },
      1);
  PointCloud cloud;
  cloud.viewpoint = Vec3::Zero();
  std::size_t total = 0;
  for (const auto& ring : rings) total += ring.size();
  cloud.points.reserve(total);
  for (const auto& ring : rings) cloud.points.insert(cloud.points.end(), ring.begin(), ring.end());
  return AddRangeNoise(cloud, options.range_noise_sigma_m, SubSeed(seed, 1u << 20));
}

PointCloud RenderLidarScan(const RayCaster& caster, const Matrix4& sensor_to_world,
                           const LidarOptions& options, std::uint64_t seed, int threads) {
  const RayCaster* world[] = {&caster};
  return RenderLidarScan(world, sensor_to_world, options, seed, threads);
}

PointCloud AddRangeNoise(const PointCloud& cloud, double sigma_m, std::uint64_t seed) {
  PointCloud noisy = cloud;
  if (sigma_m <= 0.0) return noisy;
  SeededRandom random(seed);
  for (Vec3& p : noisy.points) {
    const double range = p.norm();
    if (range > 0.0) p *= (range + sigma_m * random.Gaussian()) / range;
  }
  return noisy;
}

}  // namespace mlsreg::scan
