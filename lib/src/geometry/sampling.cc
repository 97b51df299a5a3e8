#include "mlsreg/geometry/sampling.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace mlsreg {
namespace {
__extension__ using Uint128 = unsigned __int128;
}  // namespace

double SamplingDistance(const std::vector<Vec3>& points, const KdTree& tree) {
  // Ask for a few neighbours so exact duplicates (distance 0) can be skipped.
  constexpr std::size_t kK = 4;
  std::uint32_t indices[kK];
  double d2[kK];
  double sum = 0.0;
  std::size_t counted = 0;
  for (const Vec3& p : points) {
    const std::size_t found = tree.Knn(p, kK, indices, d2);
    for (std::size_t j = 0; j < found; ++j) {
      if (d2[j] > 0.0) {
        sum += std::sqrt(d2[j]);
        ++counted;
        break;
      }
    }
  }
  return counted == 0 ? 0.0 : sum / static_cast<double>(counted);
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
  std::sort(all.begin(), all.end());
  return all;
}

}  // namespace mlsreg
