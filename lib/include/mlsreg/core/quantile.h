// The q-quantile of a set of values by rank, in linear time.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>

namespace mlsreg {

// The value of rank floor(q (n - 1)) among the n `values` (q in [0, 1]: 0 the least, 1 the
// largest), found by partial sorting: `values` is reordered. 0 when there are none.
inline double QuantileInPlace(std::span<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<std::size_t>(k)];
}

}  // namespace mlsreg
