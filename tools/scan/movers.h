// Movers: cars and pedestrians that move along a drive at their own constant speeds, as real
// streets have. They are built anew for every frame where they then are, so two frames see them
// in different places: they follow no ground truth, and a registration has to treat them as
// outliers. A car ahead at the ego car's speed even looks static in the sensor's frame.
#pragma once

#include <cstdint>
#include <vector>

#include "mlsreg/core/triangle_mesh.h"
#include "scan/drive_path.h"

namespace mlsreg::scan {

// Where movers go, relative to the drive's base poses (so that they follow the road's bends).
struct MoverLane {
  double lateral_m = 0.0;  // to the left of the drive
  double height_m = 0.0;   // of the lane's surface above the drive's road
  bool cars = true;        // cars, else pedestrians
  double direction = 1.0;  // +1 the drive's direction, -1 oncoming
};

struct Mover {
  int lane = 0;
  double start_m = 0.0;    // travelled distance along the drive at frame 0
  double speed_mps = 0.0;  // along the drive (negative: oncoming)
  int shape = 0;           // kCarShapes index for a car; a pedestrian's height in cm otherwise
};

// `count` movers spread along a drive of `length_m`: cars in the car lanes (same-direction ones
// about as fast as the ego car, `ego_speed_mps`; oncoming at 7-14 m/s), pedestrians at 1-1.6 m/s
// either way. Deterministic for a seed.
std::vector<Mover> PlaceMovers(const std::vector<MoverLane>& lanes, int count, double length_m,
                               double ego_speed_mps, std::uint64_t seed);

// The movers' mesh at `frame` (empty when none is on the drive then). A mover whose base comes
// within `keep_clear_m` of the ego car's base is left out (it would be in the car).
TriangleMesh MoversAt(const std::vector<Mover>& movers, const std::vector<MoverLane>& lanes,
                      const Drive& drive, const std::vector<double>& travelled, int frame,
                      double keep_clear_m = 6.0);

}  // namespace mlsreg::scan
