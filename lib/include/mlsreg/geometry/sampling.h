// Sampling distance (paper Eq. 11) and seeded random subsampling.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/geometry/kd_tree.h"

namespace mlsreg {

// d = mean distance from each point to its nearest other point (paper Eq. 11). Every distance
// parameter of mlsreg is a multiple of d, so nothing depends on units. Exact duplicates are
// skipped (they would pull d to zero); returns 0 for fewer than two distinct points. The same
// for any thread count.
double SamplingDistance(const std::vector<Vec3>& points, const KdTree& tree, int threads = 1);

// For each of `points[indices]`, in that order: the distance to its nearest point that is not an
// exact duplicate of it, or -1 when its 4 nearest are all duplicates. On `threads` threads.
std::vector<double> NearestDistinctDistances(const std::vector<Vec3>& points, const KdTree& tree,
                                             std::span<const std::uint32_t> indices, int threads);
// The mean of the distances NearestDistinctDistances found, in order (its -1 entries skipped);
// 0 when it found none. SamplingDistance is this over every point.
double MeanFoundDistance(std::span<const double> distances);

// `count` distinct indices in [0, size), drawn uniformly at random with the given seed and
// returned in ascending order; all indices when count >= size. Same seed, same answer, on every
// platform (std::mt19937_64 with our own bounded draw).
std::vector<std::uint32_t> RandomSubsample(std::size_t size, std::size_t count, std::uint64_t seed);

// One sample per occupied voxel of edge `h`: the one nearest the voxel's centre (lowest index on
// ties), in ascending index order.
std::vector<std::uint32_t> VoxelRepresentatives(const std::vector<Vec3>& points, double h);

}  // namespace mlsreg
