// The k-th smallest of a few hundred values without std::nth_element's hard-to-predict branches: the
// twist fit's medians and the re-binner's noise estimate.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lidar_deskew::core::detail {

/// The least (k = 0) or the largest value of read(0) .. read(n - 1).
template <typename Read>
double extremeOf(std::size_t n, std::size_t k, const Read& read) {
  double extreme = read(0);
  if (k == 0) {
    for (std::size_t i = 1; i < n; ++i)
      extreme = std::min(extreme, read(i));
  } else {
    for (std::size_t i = 1; i < n; ++i)
      extreme = std::max(extreme, read(i));
  }
  return extreme;
}

/// Smaller values of read(0) .. read(n - 1) than `pivot` to to[0, below), larger to to[above, n); each
/// value is written to both ends of the gap between them and kept where the comparisons say. The gap
/// ends up as the values equal to the pivot (none: a pivot not among them).
template <typename Read>
void partition(std::size_t n, const Read& read, double pivot, double* to, std::size_t& below,
               std::size_t& above) {
  below = 0;
  above = n;
  for (std::size_t i = 0; i < n; ++i) {
    const double value = read(i);
    to[below] = value;
    to[above - 1] = value;
    below += value < pivot ? 1 : 0;
    above -= pivot < value ? 1 : 0;
  }
}

/// The k-th smallest (from 0) of read(0) .. read(n - 1), which is what std::nth_element puts at k (the
/// values are never NaN, nor -0: the k-th smallest is one value, bit for bit), found without
/// nth_element's hard-to-predict branches: three-way partitions, each copying the values into the half
/// of `buffer` (resized to 2 n) that was not read. The first around `guess` unless it is NaN (the last
/// sweep's median of the same kind of values, which most often splits them next to k), then around a
/// median of three; the least or the largest in one pass. The result does not depend on the pivots;
/// `guess` is set to it. `read` is called in the first pass only.
template <typename Read>
double kthSmallest(std::size_t n, std::size_t k, const Read& read, std::vector<double>& buffer,
                   double& guess) {
  if (k == 0 || k + 1 == n)
    return guess = extremeOf(n, k, read);
  buffer.resize(2 * n);
  double* const halves[2] = {buffer.data(), buffer.data() + n};
  const auto medianOfThree = [](double a, double b, double c) {
    return std::max(std::min(a, b), std::min(std::max(a, b), c));
  };
  double pivot = std::isnan(guess) ? medianOfThree(read(0), read(n / 2), read(n - 1)) : guess;
  std::size_t below, above;
  partition(n, read, pivot, halves[0], below, above);
  const double* values = halves[0];
  for (int half = 1;; half = 1 - half) {
    if (k < below) {
      n = below;
    } else if (k >= above) {
      k -= above;
      n -= above;
      values += above;
    } else {
      return guess = pivot;
    }
    const auto at = [values](std::size_t i) { return values[i]; };
    if (k == 0 || k + 1 == n)
      return guess = extremeOf(n, k, at);
    pivot = medianOfThree(values[0], values[n / 2], values[n - 1]);
    partition(n, at, pivot, halves[half], below, above);
    values = halves[half];
  }
}

}  // namespace lidar_deskew::core::detail
