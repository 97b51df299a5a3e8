#include "mlsreg/geometry/sampling.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "absl/container/flat_hash_map.h"
#include "mlsreg/core/parallel_for.h"
#include "voxel_key.h"

namespace mlsreg {
namespace {

// The sample nearest a voxel's centre so far.
struct CellRepresentative {
  std::uint32_t index;
  double distance_squared;
};

}  // namespace

namespace {
__extension__ using Uint128 = unsigned __int128;
}  // namespace

std::vector<double> NearestDistinctDistances(const std::vector<Vec3>& points, const KdTree& tree,
                                             std::span<const std::uint32_t> indices, int threads) {
  std::vector<double> out(indices.size(), -1.0);
  ParallelFor(
      indices.size(), threads,
      [&](std::size_t begin, std::size_t end, int) {
        // Two neighbours (the point itself and its nearest), or a few when the second is an
        // exact duplicate (distance 0), so that duplicates can be skipped.
        constexpr std::size_t kK = 4;
        std::uint32_t found_index[kK];
        double d2[kK];
        for (std::size_t k = begin; k < end; ++k) {
          std::size_t found = tree.Knn(points[indices[k]], 2, found_index, d2);
          if (found == 2 && !(d2[1] > 0.0)) {
            found = tree.Knn(points[indices[k]], kK, found_index, d2);
          }
          for (std::size_t j = 0; j < found; ++j) {
            if (d2[j] > 0.0) {
              out[k] = std::sqrt(d2[j]);
              break;
            }
          }
        }
      },
      1024);
  return out;
}

double MeanFoundDistance(std::span<const double> distances) {
  double sum = 0.0;
  std::size_t counted = 0;
  for (const double distance : distances) {
    if (distance < 0.0) continue;
    sum += distance;
    ++counted;
  }
  return counted == 0 ? 0.0 : sum / static_cast<double>(counted);
}

double SamplingDistance(const std::vector<Vec3>& points, const KdTree& tree, int threads) {
  std::vector<std::uint32_t> all(points.size());
  std::iota(all.begin(), all.end(), 0u);
  return MeanFoundDistance(NearestDistinctDistances(points, tree, all, threads));
}

std::vector<std::uint32_t> RandomSubsample(std::size_t size, std::size_t count,
                                           std::uint64_t seed) {
  std::vector<std::uint32_t> all(size);
  std::iota(all.begin(), all.end(), 0u);
  if (count >= size) return all;
  // Partial Fisher-Yates. std::uniform_int_distribution is implementation-defined, so draw with
  // Lemire's bounded multiply to keep results identical across standard libraries.
  std::mt19937_64 rng(seed);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t range = size - i;
    const auto draw = static_cast<std::uint64_t>((static_cast<Uint128>(rng()) * range) >> 64);
    std::swap(all[i], all[i + draw]);
  }
  all.resize(count);
  if (count < size / 16) {
    std::sort(all.begin(), all.end());
    return all;
  }
  // A large share of the indices: marked and collected in order, linear in `size` where the
  // sort took count log count (a registration's finish draws half of a 40k-point source).
  std::vector<std::uint8_t> chosen(size, 0);
  for (const std::uint32_t i : all) chosen[i] = 1;
  std::size_t next = 0;
  for (std::uint32_t i = 0; i < size; ++i) {
    if (chosen[i]) all[next++] = i;
  }
  return all;
}

std::vector<std::uint32_t> VoxelRepresentatives(const std::vector<Vec3>& points, double h) {
  absl::flat_hash_map<internal::VoxelKey, CellRepresentative, internal::VoxelKeyHash> cells;
  cells.reserve(points.size() / 4 + 1);
  const double inv_h = 1.0 / h;
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    const internal::VoxelKey key = internal::KeyOf(points[i], inv_h);
    const Vec3 centre = (Vec3(key.x, key.y, key.z) + Vec3::Constant(0.5)) * h;
    const double d2 = (points[i] - centre).squaredNorm();
    auto [it, inserted] = cells.try_emplace(key, CellRepresentative{i, d2});
    if (!inserted && d2 < it->second.distance_squared) it->second = {i, d2};
  }
  std::vector<std::uint32_t> representatives;
  representatives.reserve(cells.size());
  for (const auto& [key, cell] : cells) representatives.push_back(cell.index);
  std::sort(representatives.begin(), representatives.end());
  return representatives;
}

}  // namespace mlsreg
