// The k-th smallest of a few hundred values without std::nth_element's hard-to-predict branches: the
// twist fit's medians and the re-binner's noise estimate.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lidar_deskew::core::detail {

/// How far from either end of its values k may lie for nearEnd() to finish the selection in one pass.
constexpr std::size_t kNearEnd = 3;

/// The M-th smallest (kLargest: the M-th largest, from 0) of read(0) .. read(n - 1), n > M: the M + 1
/// smallest (largest) so far kept in order, each value passed down through them by std::min and
/// std::max (no branches).
template <std::size_t M, bool kLargest, typename Read>
double orderedNearEnd(std::size_t n, const Read& read) {
  double kept[M + 1];
  for (double& value : kept)
    value = kLargest ? -INFINITY : INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    double value = read(i);
    for (std::size_t j = 0; j <= M; ++j) {
      const double held = kept[j];
      kept[j] = kLargest ? std::max(held, value) : std::min(held, value);
      value = kLargest ? std::min(held, value) : std::max(held, value);
    }
  }
  return kept[M];
}

/// The m-th smallest (kLargest: largest, from 0) of read(0) .. read(n - 1), m <= kNearEnd < n.
template <bool kLargest, typename Read>
double nearEndOf(std::size_t n, std::size_t m, const Read& read) {
  static_assert(kNearEnd == 3, "the cases below");
  switch (m) {
    case 0:
      return orderedNearEnd<0, kLargest>(n, read);
    case 1:
      return orderedNearEnd<1, kLargest>(n, read);
    case 2:
      return orderedNearEnd<2, kLargest>(n, read);
    default:
      return orderedNearEnd<3, kLargest>(n, read);
  }
}

/// The k-th smallest of read(0) .. read(n - 1) where k lies within kNearEnd of either end, in one pass.
template <typename Read>
double nearEnd(std::size_t n, std::size_t k, const Read& read) {
  const std::size_t from_top = n - 1 - k;
  return k <= from_top ? nearEndOf<false>(n, k, read) : nearEndOf<true>(n, from_top, read);
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
/// median of three; within kNearEnd of either end, in one pass (nearEnd()). The result does not depend
/// on the pivots; `guess` is set to it. `read` is called in the first pass only.
template <typename Read>
double kthSmallest(std::size_t n, std::size_t k, const Read& read, std::vector<double>& buffer,
                   double& guess) {
  if (k <= kNearEnd || n - 1 - k <= kNearEnd)
    return guess = nearEnd(n, k, read);
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
    if (k <= kNearEnd || n - 1 - k <= kNearEnd)
      return guess = nearEnd(n, k, at);
    pivot = medianOfThree(values[0], values[n / 2], values[n - 1]);
    partition(n, at, pivot, halves[half], below, above);
    values = halves[half];
  }
}

}  // namespace lidar_deskew::core::detail
