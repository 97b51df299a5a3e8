// Synthetic point sets on analytic surfaces, for tests and benchmarks.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg::testing {

// A smooth, non-symmetric height field with several bumps across [-1, 1]^2, so that a patch of
// it constrains all six degrees of freedom of a rigid motion.
inline double BumpyHeight(double x, double y) {
  return 0.12 * std::sin(5.1 * x + 0.3) * std::cos(4.3 * y - 0.2) + 0.15 * x * y +
         0.1 * std::exp(-8.0 * ((x - 0.3) * (x - 0.3) + (y + 0.4) * (y + 0.4)));
}

// `count` points uniformly at random in (x, y) over [lo, hi]^2 on z = BumpyHeight, with
// Gaussian noise of `noise` added to z.
inline PointCloud SampleBumpySurface(std::size_t count, double lo, double hi, std::uint64_t seed,
                                     double noise = 0.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> coord(lo, hi);
  std::normal_distribution<double> gauss(0.0, 1.0);
  PointCloud cloud;
  cloud.points.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double x = coord(rng), y = coord(rng);
    cloud.points.emplace_back(x, y, BumpyHeight(x, y) + noise * gauss(rng));
  }
  return cloud;
}

// A jittered grid on the plane z = 0 over [-extent, extent]^2 with spacing `spacing`.
inline PointCloud SamplePlaneGrid(double extent, double spacing, double jitter, std::uint64_t seed,
                                  double noise = 0.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  std::normal_distribution<double> gauss(0.0, 1.0);
  PointCloud cloud;
  for (double x = -extent; x <= extent + 1e-12; x += spacing) {
    for (double y = -extent; y <= extent + 1e-12; y += spacing) {
      cloud.points.emplace_back(x + u(rng), y + u(rng), noise * gauss(rng));
    }
  }
  return cloud;
}

// Uniform random points on a sphere of `radius` centred at the origin (Marsaglia), restricted
// to z > min_z.
inline PointCloud SampleSphere(std::size_t count, double radius, double min_z, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  PointCloud cloud;
  while (cloud.points.size() < count) {
    Vec3 v(gauss(rng), gauss(rng), gauss(rng));
    if (v.norm() < 1e-9) continue;
    v = radius * v.normalized();
    if (v.z() > min_z) cloud.points.push_back(v);
  }
  return cloud;
}

// An organised scan of the surface z = depth(x, y) by a pinhole camera at the origin looking
// along +z: one point per pixel, found along the pixel's ray by fixed-point iteration (the
// surface must be a gentle height field in front of the camera).
template <typename Depth>
PointCloud RenderDepthImage(const PinholeIntrinsics& camera, Depth depth) {
  PointCloud cloud;
  cloud.intrinsics = camera;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Vec3 ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      double z = 2.0;
      for (int k = 0; k < 50; ++k) z = depth(ray.x() * z, ray.y() * z);
      cloud.points.push_back(ray * z);
    }
  }
  return cloud;
}

}  // namespace mlsreg::testing
