// SeededRandom: the scanner's random draws, the same on every platform for a given seed.
// std::mt19937_64's output is fixed by the standard, but std::uniform_*_distribution and
// std::normal_distribution are not, so the draws are made here from the raw 64-bit words.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace mlsreg::scan {

class SeededRandom {
 public:
  explicit SeededRandom(std::uint64_t seed) : engine_(seed) {}

  // Uniform in [0, 1), 53 random bits.
  double Unit() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  // Uniform in [lo, hi).
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Unit(); }
  // Uniform integer in [0, n), n >= 1 (from 53 bits: exact enough for the small n used here).
  std::uint64_t Below(std::uint64_t n) {
    const auto k = static_cast<std::uint64_t>(Unit() * static_cast<double>(n));
    return k < n ? k : n - 1;
  }
  bool Chance(double probability) { return Unit() < probability; }
  // Standard normal, Box-Muller (both values of a pair are used).
  double Gaussian() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u = Unit();
    while (u <= 0.0) u = Unit();
    const double radius = std::sqrt(-2.0 * std::log(u));
    const double angle = 2.0 * std::numbers::pi * Unit();
    spare_ = radius * std::sin(angle);
    has_spare_ = true;
    return radius * std::cos(angle);
  }

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

// A seed for sub-stream `index` of `seed` (SplitMix64 of the pair), so that the streams of
// different rings, frames or objects do not overlap.
inline std::uint64_t SubSeed(std::uint64_t seed, std::uint64_t index) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

}  // namespace mlsreg::scan
