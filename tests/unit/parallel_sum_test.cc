#include "mlsreg/core/parallel_sum.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace mlsreg {
namespace {

// Terms of wildly different magnitudes: their floating-point sum depends on the order of the
// additions, so a sum split by thread would differ between thread counts.
std::vector<double> UnevenTerms(std::size_t n) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-20, 20);
  std::vector<double> terms(n);
  for (double& t : terms) t = std::ldexp(mantissa(rng), exponent(rng));
  return terms;
}

struct Sum {
  double value = 0.0;
  long count = 0;
};

Sum SumOn(const std::vector<double>& terms, int threads) {
  std::vector<Sum> partials;
  return ParallelSum(
      terms.size(), threads, partials,
      [&](std::size_t i, Sum& block) {
        block.value += terms[i];
        ++block.count;
      },
      [](Sum& total, const Sum& block) {
        total.value += block.value;
        total.count += block.count;
      });
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every thread count gives the same bits, and they are the blocks' sums added in block order;
// every index is added once (sizes below one block, at a block boundary and past it, and none).
TEST(ParallelSumTest, EveryThreadCountGivesTheBlockOrderSumBitForBit) {
  for (const std::size_t n : {std::size_t{0}, std::size_t{1}, kSumBlock - 1, kSumBlock,
                              3 * kSumBlock + 7, std::size_t{20'000}}) {
    const std::vector<double> terms = UnevenTerms(n);
    double expected = 0.0;
    for (std::size_t begin = 0; begin < n; begin += kSumBlock) {
      double block = 0.0;
      for (std::size_t i = begin; i < std::min(n, begin + kSumBlock); ++i) block += terms[i];
      expected += block;
    }
    for (const int threads : {1, 2, 3, 8}) {
      const Sum sum = SumOn(terms, threads);
      EXPECT_EQ(sum.count, static_cast<long>(n)) << n << " terms, " << threads << " threads";
      EXPECT_TRUE(SameBits(sum.value, expected))
          << n << " terms, " << threads << " threads: " << sum.value << " vs " << expected;
    }
  }
  // The terms were uneven enough for the order to matter: the plain running sum differs.
  const std::vector<double> terms = UnevenTerms(20'000);
  double running = 0.0;
  for (double t : terms) running += t;
  EXPECT_FALSE(SameBits(running, SumOn(terms, 1).value));
}

}  // namespace
}  // namespace mlsreg
