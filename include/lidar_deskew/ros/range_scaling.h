// The range field's scaling (CloudProcessor::correct: Ouster's `range` follows the correction) for a
// 32-bit integer field, four returns at a time in floats where the target has SSE2, with the cases
// the floats cannot decide left to the exact computation in doubles.
#pragma once

#if defined(__SSE2__)
#include <emmintrin.h>

namespace lidar_deskew::ros_adapter {

/// Four returns' scaled ranges estimated in floats.
struct RangeEstimates {
  __m128i rounded;  ///< each estimate rounded half away from zero (int32 lanes)
  int sure;         ///< bit i: lane i's `rounded` is the exact scaled range's, rounded
};

/// The range `values` (int32 lanes; a uint32 at or beyond 2^31 reads negative) scaled by
/// sqrt(corrected_squared / raw_squared), the squared norms of the corrected and raw positions (two
/// returns per packet), estimated in floats. The exact scaled range, value * sqrt(corrected_squared) /
/// sqrt(raw_squared) in doubles rounded half away from zero (as CloudProcessor writes a 32-bit
/// integer range), is `rounded` where `sure`: with both squares in [2^-60, 2^60] every float is normal
/// and the estimate lies within 2.7e-7 of the exact quotient relatively (six float roundings of 2^-24:
/// the two squares, the value, the quotient, its root, the product; and four double ones); where it
/// lies in [0, 2^22) and farther than 2^-21 (4.8e-7) of itself from the nearest half, both round to
/// the same whole number. Not sure elsewhere: a square out of that range or not finite, a negative or
/// huge estimate, one near a half (about 1 in 100 returns at 10 m in mm, 1 in 10 at 100 m).
inline RangeEstimates estimateRanges(__m128i values, __m128d corrected_squared_01, __m128d corrected_squared_23,
                                     __m128d raw_squared_01, __m128d raw_squared_23) {
  const __m128 corrected = _mm_movelh_ps(_mm_cvtpd_ps(corrected_squared_01), _mm_cvtpd_ps(corrected_squared_23));
  const __m128 raw = _mm_movelh_ps(_mm_cvtpd_ps(raw_squared_01), _mm_cvtpd_ps(raw_squared_23));
  const __m128 low = _mm_set1_ps(0x1p-60f), high = _mm_set1_ps(0x1p60f);
  const __m128 normal = _mm_and_ps(_mm_and_ps(_mm_cmpge_ps(corrected, low), _mm_cmple_ps(corrected, high)),
                                   _mm_and_ps(_mm_cmpge_ps(raw, low), _mm_cmple_ps(raw, high)));
  const __m128 estimate = _mm_mul_ps(_mm_cvtepi32_ps(values), _mm_sqrt_ps(_mm_div_ps(corrected, raw)));
  const __m128 in_range =
      _mm_and_ps(_mm_cmpge_ps(estimate, _mm_setzero_ps()), _mm_cmplt_ps(estimate, _mm_set1_ps(0x1p22f)));
  const __m128i whole = _mm_cvttps_epi32(estimate);
  const __m128 fraction = _mm_sub_ps(estimate, _mm_cvtepi32_ps(whole));  // exact in [0, 2^22)
  const __m128 distance = _mm_andnot_ps(_mm_set1_ps(-0.0f), _mm_sub_ps(fraction, _mm_set1_ps(0.5f)));
  const __m128 clear = _mm_cmpgt_ps(distance, _mm_mul_ps(estimate, _mm_set1_ps(0x1p-21f)));
  RangeEstimates result;
  // (a comparison's true is -1: subtracting it adds one)
  result.rounded = _mm_sub_epi32(whole, _mm_castps_si128(_mm_cmpge_ps(fraction, _mm_set1_ps(0.5f))));
  result.sure = _mm_movemask_ps(_mm_and_ps(_mm_and_ps(normal, in_range), clear));
  return result;
}

}  // namespace lidar_deskew::ros_adapter

#endif
