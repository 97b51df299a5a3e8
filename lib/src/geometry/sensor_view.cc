#include "mlsreg/geometry/sensor_view.h"

#include <algorithm>
#include <cmath>

#include "mlsreg/core/quantile.h"

namespace mlsreg {
namespace {

// Cells per cube side: coarse enough for any scan to stay in a few hundred thousand cells.
constexpr int kMinCellsPerSide = 8;
constexpr int kMaxCellsPerSide = 4096;
// Fewer usable samples than this show no sensor.
constexpr std::size_t kMinSensorSamples = 100;

}  // namespace

std::optional<SensorFinding> FindSensor(const std::vector<Vec3>& points,
                                        std::span<const std::uint32_t> sample,
                                        std::span<const double> spacing, const Vec3& candidate) {
  std::vector<double> log_range, log_spacing, angle;
  for (std::size_t k = 0; k < sample.size() && k < spacing.size(); ++k) {
    const double range = (points[sample[k]] - candidate).norm();
    if (!(spacing[k] > 0.0) || !(range > 0.0)) continue;
    log_range.push_back(std::log(range));
    log_spacing.push_back(std::log(spacing[k]));
    angle.push_back(spacing[k] / range);
  }
  if (log_range.size() < kMinSensorSamples) return std::nullopt;
  const double n = static_cast<double>(log_range.size());
  double mean_r = 0.0, mean_s = 0.0;
  for (std::size_t k = 0; k < log_range.size(); ++k) {
    mean_r += log_range[k];
    mean_s += log_spacing[k];
  }
  mean_r /= n;
  mean_s /= n;
  double covariance = 0.0, variance = 0.0;
  for (std::size_t k = 0; k < log_range.size(); ++k) {
    covariance += (log_range[k] - mean_r) * (log_spacing[k] - mean_s);
    variance += (log_range[k] - mean_r) * (log_range[k] - mean_r);
  }
  const double spread = std::exp(QuantileInPlace(log_range, 0.9) - QuantileInPlace(log_range, 0.1));
  if (!(variance > 0.0) || covariance / variance < kSensorMinSlope ||
      spread < kSensorMinRangeSpread) {
    return std::nullopt;
  }
  return SensorFinding{candidate, QuantileInPlace(angle, 0.5)};
}

SensorView SensorView::Build(const std::vector<Vec3>& points, const SensorFinding& sensor) {
  SensorView view;
  view.sensor_ = sensor.position;
  // At a face's centre a cell spans 2 / cells_per_side radians.
  const double cell_angle = kCellSteps * sensor.angular_step;
  view.cells_per_side_ =
      cell_angle > 0.0
          ? static_cast<int>(std::clamp(std::ceil(2.0 / cell_angle), double{kMinCellsPerSide},
                                        double{kMaxCellsPerSide}))
          : kMinCellsPerSide;
  view.cells_.reserve(points.size());
  for (const Vec3& p : points) {
    const Vec3 v = p - view.sensor_;
    if (const std::optional<std::uint32_t> cell = view.CellOf(v)) {
      view.cells_.emplace_back(*cell, static_cast<float>(v.norm()));
    }
  }
  std::sort(view.cells_.begin(), view.cells_.end());  // each cell's nearest range first
  view.cells_.erase(std::unique(view.cells_.begin(), view.cells_.end(),
                                [](const auto& a, const auto& b) { return a.first == b.first; }),
                    view.cells_.end());
  view.cells_.shrink_to_fit();
  return view;
}

std::optional<std::uint32_t> SensorView::CellOf(const Vec3& v) const {
  int axis = 0;
  v.cwiseAbs().maxCoeff(&axis);
  const double major = std::abs(v[axis]);
  if (!(major > 0.0)) return std::nullopt;
  const int face = 2 * axis + (v[axis] < 0.0 ? 1 : 0);
  const int n = cells_per_side_;
  const auto index = [n](double t) {  // t in [-1, 1]
    return std::clamp(static_cast<int>(std::floor((t + 1.0) * 0.5 * n)), 0, n - 1);
  };
  const int i = index(v[(axis + 1) % 3] / major);
  const int j = index(v[(axis + 2) % 3] / major);
  return static_cast<std::uint32_t>((face * n + i) * n + j);
}

std::optional<float> SensorView::NearestIn(std::uint32_t cell) const {
  const auto it =
      std::lower_bound(cells_.begin(), cells_.end(), cell,
                       [](const auto& entry, std::uint32_t c) { return entry.first < c; });
  if (it == cells_.end() || it->first != cell) return std::nullopt;
  return it->second;
}

std::optional<float> SensorView::NearestAround(std::uint32_t cell) const {
  const int n = cells_per_side_;
  const int face_base = static_cast<int>(cell) / (n * n) * n * n;
  const int i = (static_cast<int>(cell) - face_base) / n;
  const int j = (static_cast<int>(cell) - face_base) % n;
  std::optional<float> nearest;
  for (int di = -1; di <= 1; ++di) {
    for (int dj = -1; dj <= 1; ++dj) {
      if (i + di < 0 || i + di >= n || j + dj < 0 || j + dj >= n) continue;
      const std::optional<float> r =
          NearestIn(static_cast<std::uint32_t>(face_base + (i + di) * n + (j + dj)));
      if (r && (!nearest || *r < *nearest)) nearest = r;
    }
  }
  return nearest;
}

bool SensorView::Hides(const Vec3& x, double tolerance) const {
  const Vec3 v = x - sensor_;
  const std::optional<std::uint32_t> cell = CellOf(v);
  if (!cell) return false;  // at the sensor itself
  const double range = v.norm();
  std::optional<float> nearest = NearestIn(*cell);
  if (!nearest) {  // between two beams, or where the sensor saw nothing
    nearest = NearestAround(*cell);
    if (!nearest) return true;
  }
  return range > static_cast<double>(*nearest) + tolerance;
}

bool SensorView::SeesThrough(const Vec3& x, double tolerance) const {
  const Vec3 v = x - sensor_;
  const std::optional<std::uint32_t> cell = CellOf(v);
  if (!cell || !NearestIn(*cell)) return false;  // no return from x's direction: no evidence
  const std::optional<float> nearest = NearestAround(*cell);
  return v.norm() + tolerance < static_cast<double>(*nearest);
}

}  // namespace mlsreg
