#include "cli/result_clouds.h"

#include <algorithm>
#include <array>
#include <cstdint>

#include "mlsreg/io/io.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg::cli {
namespace {

// Blue at 0, green at 0.5, red at 1 (clamped).
Rgb Ramp(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const auto channel = [](double v) { return static_cast<std::uint8_t>(255.0 * v + 0.5); };
  if (t < 0.5) return {0, channel(2.0 * t), channel(1.0 - 2.0 * t)};
  return {channel(2.0 * t - 1.0), channel(2.0 - 2.0 * t), 0};
}

PointCloud Moved(const PointCloud& cloud, const Matrix4& transform) {
  PointCloud out;
  const Eigen::Matrix3d r = transform.topLeftCorner<3, 3>();
  const Vec3 t = transform.topRightCorner<3, 1>();
  out.points.reserve(cloud.size());
  for (const Vec3& p : cloud.points) out.points.push_back(r * p + t);
  for (const Vec3& n : cloud.normals) out.normals.push_back(r * n);
  out.colors = cloud.colors;
  return out;
}

}  // namespace

absl::Status WriteAlignedCloud(const std::string& path, const PointCloud& source,
                               const Matrix4& transform, const Target& target) {
  PointCloud aligned = Moved(source, transform);
  const std::vector<double> distances = DistancesToMlsSurface(target, aligned.points);
  std::vector<float> distance_d(distances.size());
  for (std::size_t i = 0; i < distances.size(); ++i) {
    distance_d[i] = static_cast<float>(distances[i] / target.sampling_distance());
  }
  if (!aligned.has_colors()) {  // the source's own colours are kept; else the ramp
    for (float d : distance_d) aligned.colors.push_back(Ramp(d / kDistanceRampMaxD));
  }
  PointAttributes attributes;
  attributes.scalars.emplace_back("distance_d", std::move(distance_d));
  return WriteCloudWithAttributes(aligned, attributes, path);
}

absl::Status WriteMergedCloud(const std::string& path, const PointCloud& source,
                              const Matrix4& transform, const Target& target) {
  PointCloud merged = Moved(source, transform);
  const std::size_t n = merged.size();
  merged.points.insert(merged.points.end(), target.points().begin(), target.points().end());
  merged.normals.clear();  // written only when every point has one
  std::vector<float> which(merged.size(), 0.0f);
  std::fill(which.begin() + static_cast<std::ptrdiff_t>(n), which.end(), 1.0f);
  merged.colors.assign(n, Rgb{255, 140, 0});
  merged.colors.resize(merged.size(), Rgb{70, 130, 180});
  PointAttributes attributes;
  attributes.scalars.emplace_back("cloud", std::move(which));
  return WriteCloudWithAttributes(merged, attributes, path);
}

}  // namespace mlsreg::cli
