// Fast Point Feature Histograms (Rusu, Blodow, Beetz 2009): 33-bin descriptors of the local
// normal geometry, used by Fast Global Registration to match points without an initial pose.
#pragma once

#include <array>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

using FpfhFeature = std::array<float, 33>;

// The most neighbours one feature is computed over (the nearest ones within the radius).
inline constexpr std::size_t kMaxFpfhNeighbors = 512;

// FPFH of every point of `points` (with unit `normals`, sign irrelevant) over the neighbours
// within `radius` among the same points (`tree` indexes them), at most kMaxFpfhNeighbors each.
// Each 11-bin block sums to 100; a point without neighbours gets all zeros. Memory is two
// features per point plus one neighbourhood: neighbourhoods are searched again in the second
// pass instead of being kept. Empty when `should_stop` said stop (asked from every thread).
// `threads` split the points; the features are the same for any count.
std::vector<FpfhFeature> ComputeFpfh(const std::vector<Vec3>& points,
                                     const std::vector<Vec3>& normals, const KdTree& tree,
                                     double radius, const StopCheck& should_stop = {},
                                     int threads = 1);

}  // namespace mlsreg
