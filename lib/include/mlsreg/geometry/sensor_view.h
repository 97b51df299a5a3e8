// SensorView: what a scan's sensor saw, direction by direction, so that a point can be asked
// whether that sensor could have seen it at all.
//
// A street scan aligned exactly on the one before covers 44-89 % of it (tuning streets): the rest
// lies behind parked cars, above its highest beam or in its blind ring. Counting those samples as
// "not covered" makes a right street pose look like a partial one. SensorView keeps, for every
// direction the sensor returned something in, the nearest range it returned there; a point is
// hidden when it lies behind that return, or in a direction where the sensor returned nothing
// and neither did its neighbours (the sky above the top beam, outside a camera's image). A point
// is seen through when it lies well in front of every return around its direction: the beams
// passed where it is, so nothing stood there when the scan was taken.
//
// The sensor is found from the sampling itself (FindSensor): a range scanner's spacing grows in
// proportion to the distance from it. An object scan measured in a frame of its own shows no
// such growth, and gets no SensorView.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

// The sensor of a scan, where its sampling shows one.
struct SensorFinding {
  Vec3 position = Vec3::Zero();
  // The median angle between neighbouring returns as seen from the sensor (radians).
  double angular_step = 0.0;
};

// The sensor at `candidate` (the file's viewpoint, else the origin) when the nearest-neighbour
// spacings of the sampled points (`spacing[k]` of `points[sample[k]]`, negative when unknown)
// grow with their distance from it: the slope of log spacing over log distance is at least
// kSensorMinSlope (about 1 for a LiDAR or camera scan in its own frame, about 0 for an object
// turned on a table and measured in its own frame), and the distances span at least
// kSensorMinRangeSpread (10th to 90th percentile).
inline constexpr double kSensorMinSlope = 0.5;
inline constexpr double kSensorMinRangeSpread = 2.5;
std::optional<SensorFinding> FindSensor(const std::vector<Vec3>& points,
                                        std::span<const std::uint32_t> sample,
                                        std::span<const double> spacing, const Vec3& candidate);

class SensorView {
 public:
  // The directions of `points` seen from `sensor`, in cells of about kCellSteps angular steps.
  static SensorView Build(const std::vector<Vec3>& points, const SensorFinding& sensor);

  // Whether the sensor could not have seen `x`: it lies more than `tolerance` behind the nearest
  // return in its direction (in its cell, or in the neighbouring cells when its own is empty: the
  // gap between two beams), or no return came from its direction or the neighbouring ones.
  bool Hides(const Vec3& x, double tolerance) const;

  // Whether the sensor saw through `x`: a return came from its direction, and every return in
  // its cell and the neighbouring ones lies more than `tolerance` beyond it (the beams passed
  // where `x` is and went on). The nearest return of the neighbourhood decides, so a surface met
  // at a grazing angle, whose range changes fast across a cell, is not seen through. A source
  // sample that a pose puts there contradicts the pose, unless it moved between the scans.
  bool SeesThrough(const Vec3& x, double tolerance) const;

  const Vec3& sensor() const { return sensor_; }
  std::size_t MemoryBytes() const { return cells_.capacity() * sizeof(cells_[0]); }

  static constexpr double kCellSteps = 3.0;

 private:
  // The cube-map cell of direction `v` (its face and the cell on it), or nothing for v = 0.
  std::optional<std::uint32_t> CellOf(const Vec3& v) const;
  // The nearest range returned in `cell`, if any.
  std::optional<float> NearestIn(std::uint32_t cell) const;
  // The nearest range returned in `cell` and the (up to) eight cells around it on its face.
  std::optional<float> NearestAround(std::uint32_t cell) const;

  Vec3 sensor_ = Vec3::Zero();
  int cells_per_side_ = 1;
  std::vector<std::pair<std::uint32_t, float>> cells_;  // (cell, nearest range), sorted by cell
};

}  // namespace mlsreg
