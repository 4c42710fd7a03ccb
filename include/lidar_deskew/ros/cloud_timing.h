// Per-point times of a sensor_msgs/PointCloud2, found from the fields the common drivers write, with no
// configuration (docs/DESIGN.md §7). Units and absolute vs relative are decided from the values
// against header.stamp; the sweep's first and last time come from the data.
#pragma once

#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "lidar_deskew/core/types.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace lidar_deskew::ros_adapter {

/// How to read a cloud's per-point time; the defaults find it alone.
struct CloudTimeConfig {
  std::string field;                ///< "" = the first present of kTimeFieldNames
  std::string unit = "auto";        ///< auto | s | ms | us | ns
  std::string base = "auto";        ///< auto | header (offsets from header.stamp) | absolute
  double max_sweep_duration = 1.0;  ///< [s] a cloud's times span at most this

  /// Throws core::InvalidInput naming the parameter (time_unit, time_base) for a bad value.
  void validate() const;
};

/// The time field names looked for, in this order: Ouster `t`, Velodyne `time`, Hesai/RoboSense/Livox
/// `timestamp`, Autoware `time_stamp`, Livox `offset_time`, laser_geometry `stamps`.
extern const char* const kTimeFieldNames[6];

/// The per-point time as found in one cloud.
struct CloudTimeField {
  std::string name;
  std::uint8_t datatype = 0;  ///< sensor_msgs::PointField datatype
  std::uint32_t offset = 0;   ///< within a point
  bool absolute = false;      ///< values are times, not offsets from header.stamp
  double unit = 1.0;          ///< [s] per value unit (1e-9 for ns)

  /// "t (uint32, ns, from header.stamp)", for logs.
  std::string describe() const;
};

/// The layout of a cloud checked against its data: little-endian, point_step holding every field,
/// data holding height x row_step (and at most 4 GiB, as a message can), row_step holding width x
/// point_step. Throws core::InvalidInput naming the bad field.
void checkCloudLayout(const sensor_msgs::PointCloud2& cloud);

/// Byte offset of point `index` (row-major over height x width) in cloud.data.
inline std::size_t pointOffset(const sensor_msgs::PointCloud2& cloud, std::size_t index) {
  return (index / cloud.width) * cloud.row_step + (index % cloud.width) * cloud.point_step;
}

/// Calls visit(T{}) with the C++ type of a PointField datatype (std::uint8_t .. double); false for an
/// unknown datatype. One switch per field, not per value: the loop inside `visit` is typed.
template <typename Visit>
bool withFieldType(std::uint8_t datatype, Visit&& visit) {
  switch (datatype) {
    case sensor_msgs::PointField::INT8:
      return visit(std::int8_t{}), true;
    case sensor_msgs::PointField::UINT8:
      return visit(std::uint8_t{}), true;
    case sensor_msgs::PointField::INT16:
      return visit(std::int16_t{}), true;
    case sensor_msgs::PointField::UINT16:
      return visit(std::uint16_t{}), true;
    case sensor_msgs::PointField::INT32:
      return visit(std::int32_t{}), true;
    case sensor_msgs::PointField::UINT32:
      return visit(std::uint32_t{}), true;
    case sensor_msgs::PointField::FLOAT32:
      return visit(float{}), true;
    case sensor_msgs::PointField::FLOAT64:
      return visit(double{}), true;
  }
  return false;
}

/// A finite `value` as a field value of type T (a PointField datatype's): within T's range, and for an
/// integer type rounded half away from zero first, as std::round does. Done inline (std::round is a
/// libm call per value here): PointField's integers have at most 32 bits, so a value strictly between
/// their bounds truncates exactly through int64, and its fraction (value minus that) is exact.
template <typename T>
T toFieldValue(double value) {
  constexpr double lowest = static_cast<double>(std::numeric_limits<T>::lowest());
  constexpr double highest = static_cast<double>(std::numeric_limits<T>::max());
  if constexpr (std::is_integral_v<T>) {
    static_assert(sizeof(T) <= 4, "PointField integers have at most 32 bits");
    if (value >= highest)
      return std::numeric_limits<T>::max();
    if (value <= lowest)
      return std::numeric_limits<T>::lowest();
    auto whole = static_cast<std::int64_t>(value);
    const double fraction = value - static_cast<double>(whole);
    whole += static_cast<std::int64_t>(fraction >= 0.5) - static_cast<std::int64_t>(fraction <= -0.5);
    return static_cast<T>(whole);
  } else {
    return static_cast<T>(std::clamp(value, lowest, highest));
  }
}

/// toFieldValue() of two finite values at once, equal to it value by value: for an integer type in SSE2
/// where the target has it (clamped, then rounded half away from zero in doubles: |value| to the
/// nearest whole number by adding and subtracting 2^52, less one where that rounded up, plus one where
/// the fraction left is 0.5 or more); one value at a time otherwise.
template <typename T>
inline void toFieldValues(double first, double second, T& first_value, T& second_value) {
#if defined(__SSE2__)
  if constexpr (std::is_integral_v<T>) {
    static_assert(sizeof(T) <= 4, "PointField integers have at most 32 bits");
    constexpr double lowest = static_cast<double>(std::numeric_limits<T>::lowest());
    constexpr double highest = static_cast<double>(std::numeric_limits<T>::max());
    // (the bounds are whole numbers: clamping first, the rounding keeps them)
    const __m128d clamped =
        _mm_min_pd(_mm_max_pd(_mm_set_pd(second, first), _mm_set1_pd(lowest)), _mm_set1_pd(highest));
    const __m128d sign = _mm_set1_pd(-0.0);
    const __m128d magnitude = _mm_andnot_pd(sign, clamped);  // below 2^32: rounds exactly at 2^52
    const __m128d two_52 = _mm_set1_pd(4503599627370496.0);
    const __m128d nearest = _mm_sub_pd(_mm_add_pd(magnitude, two_52), two_52);
    const __m128d one = _mm_set1_pd(1.0);
    const __m128d whole = _mm_sub_pd(nearest, _mm_and_pd(_mm_cmpgt_pd(nearest, magnitude), one));
    const __m128d fraction = _mm_sub_pd(magnitude, whole);  // exact
    const __m128d rounded = _mm_or_pd(
        _mm_add_pd(whole, _mm_and_pd(_mm_cmpge_pd(fraction, _mm_set1_pd(0.5)), one)), _mm_and_pd(clamped, sign));
    if constexpr (std::is_same_v<T, std::uint32_t>) {  // beyond int32: shifted into its range and back
      const __m128i shifted = _mm_cvttpd_epi32(_mm_sub_pd(rounded, _mm_set1_pd(2147483648.0)));
      const __m128i values = _mm_xor_si128(shifted, _mm_set1_epi32(static_cast<int>(0x80000000u)));
      first_value = static_cast<T>(static_cast<std::uint32_t>(_mm_cvtsi128_si32(values)));
      second_value = static_cast<T>(static_cast<std::uint32_t>(_mm_cvtsi128_si32(_mm_srli_si128(values, 4))));
    } else {
      const __m128i values = _mm_cvttpd_epi32(rounded);
      first_value = static_cast<T>(_mm_cvtsi128_si32(values));
      second_value = static_cast<T>(_mm_cvtsi128_si32(_mm_srli_si128(values, 4)));
    }
    return;
  }
#endif
  first_value = toFieldValue<T>(first);
  second_value = toFieldValue<T>(second);
}

/// Bytes of a value of a PointField datatype; 0 for an unknown one.
std::size_t fieldSize(std::uint8_t datatype);

/// Reads a numeric field of the point at byte offset `at` (of any PointField datatype) as a double.
double readNumber(const std::uint8_t* point, std::uint8_t datatype);

/// The time field `config` names, or else the first of kTimeFieldNames the cloud has; null when none.
const sensor_msgs::PointField* timeFieldOf(const sensor_msgs::PointCloud2& cloud,
                                           const CloudTimeConfig& config);

/// The error for a cloud without a time field: names the fields it has.
core::InvalidInput noTimeField(const sensor_msgs::PointCloud2& cloud, const CloudTimeConfig& config);

/// Decides the unit and base of a time field from its values' range [low, high] over the returns
/// (low > high: none) against header.stamp: absolute when, in some unit, the values lie within
/// max_sweep_duration + 1 s of header.stamp; otherwise offsets from header.stamp in the first unit in
/// which they span at most max_sweep_duration (integer fields tried as ns, us, ms, s; floating ones as
/// s, ms, us, ns: the drivers' own units come first). Near time 0 (header.stamp within twice that
/// window: a simulator's clock) offsets are tried first, as the two look alike there. time_unit or
/// time_base alone narrow the choice; both given decide it. Throws core::InvalidInput("time field")
/// when the values fit no unit.
CloudTimeField decideTimeField(const sensor_msgs::PointField& field, double low, double high,
                               core::TimeNs stamp, const CloudTimeConfig& config);

/// The absolute time [ns] of a time field value (as decided for the field), exact to what the value
/// holds; increases with the value. The value times the unit must lie within ROS time.
core::TimeNs timeOf(const CloudTimeField& field, core::TimeNs stamp, double value);

/// timeFieldOf() and decideTimeField() over a whole cloud in index order (the node reads a cloud in
/// one pass in CloudProcessor::prepare instead): finds the time field and decides it from the values of
/// the returns (`returns[i]`; every point when null). Throws core::InvalidInput("time field") naming
/// the cloud's fields when there is none, or when its values fit no unit. The layout must be checked.
CloudTimeField findTimeField(const sensor_msgs::PointCloud2& cloud, const CloudTimeConfig& config,
                             const std::vector<bool>* returns = nullptr);

/// Absolute time [ns] of every point, in index order (of a no-return point, when `returns` says so:
/// header.stamp, its value unread). A non-finite time of a return is an error (core::InvalidInput
/// naming the field).
void pointTimes(const sensor_msgs::PointCloud2& cloud, const CloudTimeField& field,
                std::vector<core::TimeNs>& times, const std::vector<bool>* returns = nullptr);

}  // namespace lidar_deskew::ros_adapter
