#include "lidar_deskew/ros/cloud_processor.h"

#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "../core/simd.h"
#include "lidar_deskew/ros/cloud_azimuth.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/range_scaling.h"
#include "lidar_deskew/ros/scan_processor.h"

namespace lidar_deskew::ros_adapter {
namespace {

using sensor_msgs::PointField;

/// The x, y or z field: float32 or float64.
const PointField& coordinateField(const sensor_msgs::PointCloud2& cloud, const std::string& name) {
  for (const PointField& field : cloud.fields) {
    if (field.name != name)
      continue;
    if (field.datatype != PointField::FLOAT32 && field.datatype != PointField::FLOAT64)
      throw core::InvalidInput("fields", name + " is neither float32 nor float64");
    return field;
  }
  throw core::InvalidInput("fields", "no " + name + " field");
}

/// True when the values of two fields (of known datatypes) share a byte: writing one would change
/// the other.
bool overlap(const PointField& a, const PointField& b) {
  return a.offset < b.offset + fieldSize(b.datatype) && b.offset < a.offset + fieldSize(a.datatype);
}

/// Calls visit(std::bool_constant<flag>{}): a run-time flag as a template's.
template <typename Visit>
void withFlag(bool flag, Visit&& visit) {
  if (flag)
    visit(std::true_type{});
  else
    visit(std::false_type{});
}

/// The x, y and z fields, of one datatype, apart.
struct Coordinates {
  explicit Coordinates(const sensor_msgs::PointCloud2& cloud)
      : x(coordinateField(cloud, "x")), y(coordinateField(cloud, "y")), z(coordinateField(cloud, "z")) {
    if (y.datatype != x.datatype || z.datatype != x.datatype)
      throw core::InvalidInput("fields", "x, y and z differ in datatype");
    if (overlap(x, y) || overlap(x, z) || overlap(y, z))
      throw core::InvalidInput("fields", "x, y and z overlap");
  }
  /// Calls visit(T{}) with their C++ type.
  template <typename Visit>
  void withType(Visit&& visit) const {
    if (x.datatype == PointField::FLOAT32)
      visit(float{});
    else
      visit(double{});
  }
  /// Calls visit(T{}, std::bool_constant<y follows x>{}): their C++ type, and whether y lies right
  /// after x (y.offset == x.offset + sizeof(T)).
  template <typename Visit>
  void withTypeAndPairing(Visit&& visit) const {
    withType([&](auto coordinate) {
      withFlag(y.offset == x.offset + sizeof coordinate, [&](auto adjacent) { visit(coordinate, adjacent); });
    });
  }
  const PointField& x;
  const PointField& y;
  const PointField& z;
};

/// The field of that name holding one number, when it is none of `others` and shares no byte with them
/// (null otherwise).
const PointField* separateField(const sensor_msgs::PointCloud2& cloud, const std::string& name,
                                const std::vector<const PointField*>& others) {
  for (const PointField& field : cloud.fields) {
    if (field.name != name || field.count > 1)
      continue;
    for (const PointField* other : others)
      if (other != nullptr && (other == &field || overlap(field, *other)))
        return nullptr;
    return &field;
  }
  return nullptr;
}

/// The field of that name, or null.
const PointField* fieldNamed(const sensor_msgs::PointCloud2& cloud, const std::string& name) {
  for (const PointField& field : cloud.fields)
    if (field.name == name)
      return &field;
  return nullptr;
}

template <typename T>
T load(const std::uint8_t* at) {
  T value;
  std::memcpy(&value, at, sizeof value);
  return value;
}

template <typename T>
void store(std::uint8_t* at, T value) {
  std::memcpy(at, &value, sizeof value);
}

}  // namespace

CloudProcessor::CloudProcessor(const DeskewParams& params)
    : params_(params),
      time_config_(params.cloud_time),
      time_offset_(core::secondsToNs(params.timing.time_offset)),
      deskewer_(params.deskew) {
  time_config_.max_sweep_duration = params.timing.max_sweep_duration;
  time_config_.validate();
  // The planar scan's band and grid, pairwise (each bound alone is checked with the parameters).
  if (params.cloud_scan.height_max < params.cloud_scan.height_min)
    throw core::InvalidInput("scan_height_max", "must not be below scan_height_min");
  if (params.cloud_scan.angle_max <= params.cloud_scan.angle_min)
    throw core::InvalidInput("scan_angle_max", "must be above scan_angle_min");
}

namespace {

constexpr std::uint32_t kNoFiring = std::numeric_limits<std::uint32_t>::max();

/// Groups returns by their time value as they are read: consecutive returns of one value, and in an
/// organized cloud (read row by row) the returns of a column that share its value (a multi-line
/// LIDAR's column fires at once).
class FiringGrouper {
 public:
  /// `columns`: the organized cloud's width; 0 for a dense cloud.
  explicit FiringGrouper(std::size_t columns) : of_column_(columns, kNoFiring) {}

  /// The return read before, in a sequence of calls: a local of the caller's, so that it stays in
  /// registers across a loop that stores points.
  struct Last {
    std::uint32_t firing = kNoFiring;
    double value = 0.0;
  };

  /// The firing of a return of time value `value` in column `column`.
  std::uint32_t firingOf(double value, std::uint32_t column, Last& last) {
    return of_column_.empty() ? firingOf<false>(value, column, last) : firingOf<true>(value, column, last);
  }
  /// The same, knowing whether the cloud is organized (its columns are kept).
  template <bool kOrganized>
  std::uint32_t firingOf(double value, std::uint32_t column, Last& last) {
    if (value == last.value && last.firing != kNoFiring)
      return last.firing;
    std::uint32_t firing = kOrganized ? of_column_[column] : kNoFiring;
    if (firing == kNoFiring || values_[firing] != value) {
      firing = static_cast<std::uint32_t>(values_.size());
      values_.push_back(value);
      if (kOrganized)
        of_column_[column] = firing;
    }
    last.firing = firing;
    last.value = value;
    return firing;
  }
  /// The value of each firing.
  const std::vector<double>& values() const { return values_; }

 private:
  std::vector<std::uint32_t> of_column_;
  std::vector<double> values_;
};

/// A return: finite coordinates, not all zero (range 0 is "no return" for Ouster and others). Floats in
/// one test of their squared norm in double, which no float overflows and none but zero makes 0 (NaN
/// fails both comparisons).
inline bool isReturn(float x, float y, float z) {
  const double dx = x, dy = y, dz = z;
  const double squared = (dx * dx + dy * dy) + dz * dz;
  return squared > 0.0 && squared <= std::numeric_limits<double>::max();
}
inline bool isReturn(double x, double y, double z) {
  const Eigen::Vector3d p(x, y, z);
  return p.allFinite() && !p.isZero(0.0);
}

/// Reads the returns of `cloud` (finite coordinates of type T, not exactly the origin: range 0 is "no
/// return" for Ouster and others) in the cloud's order into `prepared` (points, byte offsets and, by
/// the value of their time field of type TimeType, their firings; void: not read). kAdjacentXYZ: y and
/// z follow x (every driver's layout: their offsets are constants of the loop); kOrganized: the cloud is
/// organized (height above 1: `grouper` keeps its columns). Also built for AVX2 (as
/// writeReturnsAndRanges).
template <typename T, typename TimeType, bool kAdjacentXYZ, bool kOrganized>
LIDAR_DESKEW_AVX2_CLONES void readReturns(const sensor_msgs::PointCloud2& cloud, const Coordinates& xyz,
                                          std::uint32_t time_offset, PreparedCloud& prepared,
                                          FiringGrouper& grouper) {
  const std::size_t count = static_cast<std::size_t>(cloud.width) * cloud.height;
  prepared.points.resize(count);
  prepared.byte_offsets.resize(count);
  prepared.firings.of_point.resize(std::is_void_v<TimeType> ? 0 : count);
  // Each field from x's byte: fewer offsets held over the loop. (No point: data may be null.)
  const std::uint8_t* const data = count == 0 ? cloud.data.data() : cloud.data.data() + xyz.x.offset;
  const auto from_x = [&](std::uint32_t offset) {
    return static_cast<std::ptrdiff_t>(offset) - static_cast<std::ptrdiff_t>(xyz.x.offset);
  };
  const std::ptrdiff_t y = kAdjacentXYZ ? static_cast<std::ptrdiff_t>(sizeof(T)) : from_x(xyz.y.offset);
  const std::ptrdiff_t z = kAdjacentXYZ ? static_cast<std::ptrdiff_t>(2 * sizeof(T)) : from_x(xyz.z.offset);
  const std::ptrdiff_t time = from_x(time_offset);
  Eigen::Vector3d* const points = prepared.points.data();
  std::uint32_t* const byte_offsets = prepared.byte_offsets.data();
  std::uint32_t* const firings = prepared.firings.of_point.data();
  std::size_t returns = 0;
  FiringGrouper::Last last;
  // (rows of no point are not walked: a width of 0 may come with any height, and row_step 0)
  // (the layout in locals: the stores below may alias the message's uint32 members for the compiler)
  const std::uint32_t width = cloud.width, row_step = cloud.row_step, point_step = cloud.point_step;
  const std::uint32_t rows = width == 0 ? 0 : cloud.height;
  for (std::uint32_t row = 0; row < rows; ++row) {
    for (std::uint32_t column = 0; column < width; ++column) {
      const auto at = static_cast<std::uint32_t>(row * row_step + column * point_step);
      const std::uint8_t* const point = data + at;
      const T px = load<T>(point), py = load<T>(point + y), pz = load<T>(point + z);
      if (!isReturn(px, py, pz))
        continue;
      points[returns] = Eigen::Vector3d(px, py, pz);
      byte_offsets[returns] = at;
      if constexpr (!std::is_void_v<TimeType>)
        firings[returns] =
            grouper.firingOf<kOrganized>(static_cast<double>(load<TimeType>(point + time)), column, last);
      ++returns;
    }
  }
  prepared.points.resize(returns);
  prepared.byte_offsets.resize(returns);
  prepared.firings.of_point.resize(std::is_void_v<TimeType> ? 0 : returns);
}

/// Stores a corrected position as x y z of type T at `point`'s offsets x, y, z; kAdjacentXY: y follows x
/// (y == x + sizeof(T), as in every driver's layout): x and y converted and stored as a pair, in one
/// SSE2 store (the conversion is cvtsd2ss's, two at a time).
template <typename T, bool kAdjacentXY>
inline void storePosition(std::uint8_t* point, std::uint32_t x, std::uint32_t y, std::uint32_t z,
                          const Eigen::Vector3d& position) {
#if defined(__SSE2__)
  if constexpr (kAdjacentXY) {
    const __m128d xy = _mm_loadu_pd(position.data());
    if constexpr (std::is_same_v<T, float>)
      _mm_storel_epi64(reinterpret_cast<__m128i*>(point + x), _mm_castps_si128(_mm_cvtpd_ps(xy)));
    else
      _mm_storeu_pd(reinterpret_cast<double*>(point + x), xy);
    store(point + z, static_cast<T>(position.z()));
    return;
  }
#endif
  store(point + x, static_cast<T>(position.x()));
  store(point + y, static_cast<T>(position.y()));
  store(point + z, static_cast<T>(position.z()));
}

/// Writes the corrected positions of `count` returns (x y z of type T) at their byte offsets in `data`
/// (the output's), and `time_value` into their time field (of type TimeType at `time_offset`; none for
/// void).
template <typename T, bool kAdjacentXY, typename TimeType>
void writeReturns(const Coordinates& xyz, std::uint32_t time_offset, double time_value,
                  const std::uint32_t* byte_offsets, const Eigen::Vector3d* corrected, std::size_t count,
                  std::uint8_t* data) {
  const std::uint32_t x = xyz.x.offset, y = xyz.y.offset, z = xyz.z.offset;
  for (std::size_t k = 0; k < count; ++k) {
    std::uint8_t* const point = data + byte_offsets[k];
    storePosition<T, kAdjacentXY>(point, x, y, z, corrected[k]);
    if constexpr (!std::is_void_v<TimeType>)
      store(point + time_offset, static_cast<TimeType>(time_value));
  }
}

#if defined(__SSE2__)
/// The squared norms of two consecutive positions, p[0] and p[1], as a packet: their six coordinates
/// squared in three packets and summed lane-wise ((x^2 + y^2) + z^2 for the first, (y^2 + z^2) + x^2
/// for the second: an estimate's input, not squaredNorm() to the bit).
inline __m128d squaredNorms(const Eigen::Vector3d* p) {
  static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "positions packed in an array");
  const double* const coordinates = p->data();
  const __m128d x0y0 = _mm_loadu_pd(coordinates), z0x1 = _mm_loadu_pd(coordinates + 2),
                y1z1 = _mm_loadu_pd(coordinates + 4);
  const __m128d a = _mm_mul_pd(x0y0, x0y0), b = _mm_mul_pd(z0x1, z0x1), c = _mm_mul_pd(y1z1, y1z1);
  return _mm_add_pd(_mm_add_pd(_mm_unpacklo_pd(a, c), _mm_unpackhi_pd(a, c)), b);
}
#endif

/// Writes the corrected positions of `count` returns (x y z of type T) at their byte offsets in `data`
/// (the output's), and scales their `range` field (of type R, any unit, at `range_offset`) by the ratio
/// of the corrected position's distance from the sensor to the raw one's: the range of the corrected
/// point, in the driver's unit and from the driver's own origin (Ouster's beam origin lies a few cm from
/// the sensor frame's: a still sensor's ranges stay as they were). Integers are rounded; values kept
/// within their type; a value that is not finite, or would not be, is left as it was. kTime4: also
/// writes `time_bits`, the bytes of a 4-byte time field's new value, at `time_offset` (Ouster's uint32
/// t: no second pass over the block; only with a 32-bit integer range). Also built for AVX2 (VEX
/// three-operand forms of the same operations, no FMA: the same bits; 40 -> 33 instructions per
/// return on an OS1-64 cloud).
template <typename T, bool kAdjacentXY, typename R, bool kTime4 = false>
LIDAR_DESKEW_AVX2_CLONES void writeReturnsAndRanges(const Coordinates& xyz, std::uint32_t range_offset,
                                                    const std::uint32_t* byte_offsets,
                                                    const Eigen::Vector3d* raw,
                                                    const Eigen::Vector3d* corrected, std::size_t count,
                                                    std::uint8_t* data, std::uint32_t time_offset = 0,
                                                    std::uint32_t time_bits = 0) {
  static_assert(!kTime4 || (std::is_integral_v<R> && sizeof(R) == 4), "a time field written with 32-bit ranges only");
  const std::uint32_t x = xyz.x.offset, y = xyz.y.offset, z = xyz.z.offset;
  // x y z, and the time field when kTime4: a return's position.
  const auto writePosition = [&](std::uint8_t* point, const Eigen::Vector3d& position) {
    storePosition<T, kAdjacentXY>(point, x, y, z, position);
    if constexpr (kTime4)
      store(point + time_offset, time_bits);
  };
  const auto value = [&](const std::uint8_t* point) { return static_cast<double>(load<R>(point + range_offset)); };
  // One return's range alone: value * |corrected| / |raw| (norm() is the square root of squaredNorm()).
  const auto writeRange = [&](std::uint8_t* point, const Eigen::Vector3d& corrected_position,
                              const Eigen::Vector3d& raw_position) {
    const double scaled = value(point) * corrected_position.norm() / raw_position.norm();
    if (std::isfinite(scaled))  // (a non-finite value, or a non-finite correction: left as it was)
      store(point + range_offset, toFieldValue<R>(scaled));
  };
  std::size_t k = 0;
#if defined(__SSE2__)
  // A 32-bit integer range (Ouster's uint32 mm), four returns at a time: estimated in floats, in
  // doubles only where the estimate cannot tell the rounded value (estimateRanges: a few per cent).
  // Two double square roots and a division per return bounded the loop below.
  if constexpr (std::is_integral_v<R> && sizeof(R) == 4) {
    for (; k + 3 < count; k += 4) {
      std::uint8_t* const points[4] = {data + byte_offsets[k], data + byte_offsets[k + 1],
                                       data + byte_offsets[k + 2], data + byte_offsets[k + 3]};
      const Eigen::Vector3d* const c = corrected + k;
      const Eigen::Vector3d* const r = raw + k;
      const RangeEstimates estimates = estimateRanges(
          _mm_setr_epi32(load<std::int32_t>(points[0] + range_offset), load<std::int32_t>(points[1] + range_offset),
                         load<std::int32_t>(points[2] + range_offset), load<std::int32_t>(points[3] + range_offset)),
          squaredNorms(c), squaredNorms(c + 2), squaredNorms(r), squaredNorms(r + 2));
      for (int i = 0; i < 4; ++i)
        writePosition(points[i], c[i]);
      alignas(16) std::int32_t rounded[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(rounded), estimates.rounded);
      if (estimates.sure == 0xf) {
        for (int i = 0; i < 4; ++i)
          store(points[i] + range_offset, static_cast<R>(rounded[i]));
        continue;
      }
      for (int i = 0; i < 4; ++i) {
        if ((estimates.sure >> i & 1) != 0)
          store(points[i] + range_offset, static_cast<R>(rounded[i]));
        else
          writeRange(points[i], c[i], r[i]);
      }
    }
  }
#endif
  // Two returns at a time: their square roots and quotients in packets (Eigen's, IEEE's as
  // std::sqrt's), their conversions to R too (toFieldValues). Three scalar roots and divisions per
  // return bounded the loop; the writes take the time they leave.
  for (; k + 1 < count; k += 2) {
    std::uint8_t* const first = data + byte_offsets[k];
    std::uint8_t* const second = data + byte_offsets[k + 1];
    const Eigen::Array2d values(value(first), value(second));
    const Eigen::Array2d corrected_squared(corrected[k].squaredNorm(), corrected[k + 1].squaredNorm());
    const Eigen::Array2d raw_squared(raw[k].squaredNorm(), raw[k + 1].squaredNorm());
    const Eigen::Array2d scaled = values * corrected_squared.sqrt() / raw_squared.sqrt();
    writePosition(first, corrected[k]);
    writePosition(second, corrected[k + 1]);
    // (a non-finite value, or a non-finite correction: left as it was)
    const bool first_finite = std::isfinite(scaled[0]), second_finite = std::isfinite(scaled[1]);
    R first_value, second_value;
    toFieldValues<R>(first_finite ? scaled[0] : 0.0, second_finite ? scaled[1] : 0.0, first_value,
                     second_value);
    if (first_finite)
      store(first + range_offset, first_value);
    if (second_finite)
      store(second + range_offset, second_value);
  }
  if (k < count) {
    std::uint8_t* const point = data + byte_offsets[k];
    writePosition(point, corrected[k]);
    writeRange(point, corrected[k], raw[k]);
  }
}

/// Writes `time_value` into the time field (of type TimeType, at `time_offset`) of `count` returns.
template <typename TimeType>
void writeTimes(std::uint32_t time_offset, double time_value, const std::uint32_t* byte_offsets, std::size_t count,
                std::uint8_t* data) {
  const auto typed = static_cast<TimeType>(time_value);
  for (std::size_t k = 0; k < count; ++k)
    store(data + byte_offsets[k] + time_offset, typed);
}

/// Times the returns of a cloud without a time field from their azimuth (azimuth_timing): each one's
/// offset [s] from the stamp, as a float64 field in seconds would hold it, grouped into firings. An
/// organized cloud is handed over column by column, no-returns as NaN: a column was fired together.
void timeByAzimuth(const AzimuthTiming& timing, PreparedCloud& prepared, FiringGrouper& grouper) {
  const sensor_msgs::PointCloud2& cloud = *prepared.message;
  const std::size_t returns = prepared.points.size();
  std::vector<double> offsets(returns);
  std::vector<std::uint32_t> columns(returns, 0);
  if (cloud.height <= 1) {  // a dense cloud: in firing order as it is
    azimuthOffsets(prepared.points, timing, offsets);
  } else {
    const std::size_t height = cloud.height;
    std::vector<Eigen::Vector3d> by_column(
        static_cast<std::size_t>(cloud.width) * height,
        Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    std::vector<std::size_t> entries(returns);
    for (std::size_t i = 0; i < returns; ++i) {
      const std::size_t row = prepared.byte_offsets[i] / cloud.row_step;
      columns[i] =
          static_cast<std::uint32_t>((prepared.byte_offsets[i] - row * cloud.row_step) / cloud.point_step);
      entries[i] = columns[i] * height + row;
      by_column[entries[i]] = prepared.points[i];
    }
    std::vector<double> by_column_offsets;
    azimuthOffsets(by_column, timing, by_column_offsets, height);
    for (std::size_t i = 0; i < returns; ++i)
      offsets[i] = by_column_offsets[entries[i]];
  }
  prepared.firings.of_point.resize(returns);
  FiringGrouper::Last last;
  for (std::size_t i = 0; i < returns; ++i)
    prepared.firings.of_point[i] = grouper.firingOf(offsets[i], columns[i], last);
  prepared.time_field.datatype = PointField::FLOAT64;  // name "": no field to rewrite
}

}  // namespace

PreparedCloud CloudProcessor::prepare(const sensor_msgs::PointCloud2::ConstPtr& message) const {
  const sensor_msgs::PointCloud2& cloud = *message;
  if (cloud.header.frame_id.empty())
    throw core::InvalidInput("header.frame_id", "is empty");
  checkCloudLayout(cloud);
  const Coordinates xyz(cloud);
  const PointField* const time_field = timeFieldOf(cloud, time_config_);
  PreparedCloud prepared;
  prepared.message = message;
  const bool by_azimuth = time_field == nullptr && params_.azimuth.enabled;
  if (time_field == nullptr && !by_azimuth)
    throw noTimeField(cloud, time_config_);
  const std::string time_source = by_azimuth ? "the azimuth" : time_field->name;
  // The time field is rewritten after x y z: it must not overlap them.
  if (time_field != nullptr &&
      (overlap(*time_field, xyz.x) || overlap(*time_field, xyz.y) || overlap(*time_field, xyz.z)))
    throw core::InvalidInput("fields", "the time field " + time_field->name + " overlaps x, y or z");

  // One pass over the data: the returns, grouped into firings by their time field's value. Only the
  // returns' times count: a no-return point may carry any time, or none.
  const bool organized = cloud.height > 1;
  FiringGrouper grouper(organized ? cloud.width : 0);
  xyz.withType([&](auto coordinate) {
    using T = decltype(coordinate);
    const bool adjacent = xyz.y.offset == xyz.x.offset + sizeof(T) && xyz.z.offset == xyz.x.offset + 2 * sizeof(T);
    withFlag(adjacent, [&](auto adjacent_xyz) {
      withFlag(organized, [&](auto organized_cloud) {
        constexpr bool kAdjacentXYZ = decltype(adjacent_xyz)::value, kOrganized = decltype(organized_cloud)::value;
        if (time_field == nullptr) {
          readReturns<T, void, kAdjacentXYZ, kOrganized>(cloud, xyz, 0, prepared, grouper);
          return;
        }
        withFieldType(time_field->datatype, [&](auto time) {
          readReturns<T, decltype(time), kAdjacentXYZ, kOrganized>(cloud, xyz, time_field->offset, prepared,
                                                                   grouper);
        });
      });
    });
  });
  const std::size_t returns = prepared.points.size();
  const core::TimeNs stamp = toNs(cloud.header.stamp);
  if (by_azimuth)
    timeByAzimuth(params_.azimuth, prepared, grouper);
  // Every return's value is its firing's: the range over the firings is the range over the returns.
  const std::vector<double>& values = grouper.values();
  double low = std::numeric_limits<double>::infinity();
  double high = -low;
  for (double value : values) {
    if (!std::isfinite(value))
      throw core::InvalidInput("time field", time_source + " is not finite at some returns");
    low = std::min(low, value);
    high = std::max(high, value);
  }
  if (!by_azimuth)
    prepared.time_field = decideTimeField(*time_field, low, high, stamp, time_config_);
  const CloudTimeField& field = prepared.time_field;
  // Within ROS time (less 100 s) before any conversion.
  constexpr double kLatestTime = 4294967296.0 - 100.0;  // [s]
  const double shift = field.absolute ? 0.0 : core::nsToSeconds(stamp);
  if (returns > 0 && !(low * field.unit + shift >= 0.0 && high * field.unit + shift <= kLatestTime))
    throw core::InvalidInput("time field", "puts the sweep outside the range of ROS time");
  // The sweep's ends: the times of the lowest and highest value, as a time grows with its value.
  prepared.first = returns == 0 ? stamp : timeOf(field, stamp, low);
  prepared.last = returns == 0 ? stamp : timeOf(field, stamp, high);
  if (core::nsToSeconds(prepared.last - prepared.first) > params_.timing.max_sweep_duration) {
    throw core::InvalidInput("time field",
                             time_source + " spans " +
                                 formatNumber(core::nsToSeconds(prepared.last - prepared.first)) +
                                 " s, more than max_sweep_duration");
  }
  prepared.firings.offsets.reserve(values.size());
  prepared.firing_times.reserve(values.size());
  for (double value : values) {
    const core::TimeNs time = timeOf(field, stamp, value);
    prepared.firing_times.push_back(time + time_offset_);
    prepared.firings.offsets.push_back(core::nsToSeconds(time - prepared.first));
  }
  // time_offset: every time later by the same amount (the offsets from `first` stay).
  prepared.first += time_offset_;
  prepared.last += time_offset_;
  if (prepared.first < 0)
    throw core::InvalidInput("time_offset", "puts the sweep before the start of ROS time");
  return prepared;
}

CloudOutputs CloudProcessor::correct(const PreparedCloud& prepared, const mrpt::poses::CPose3D& mount,
                                     const core::MotionSource& motion) {
  checkTfGaps(params_.max_tf_gap, motion, prepared.first, prepared.last);
  const core::TimeNs reference =
      deskewer_.beginFirings(prepared.points, prepared.firings, prepared.first, mount, motion);

  // The output: the input's header and layout; its data copied below, a block at a time.
  const sensor_msgs::PointCloud2& input = *prepared.message;
  auto output = boost::make_shared<sensor_msgs::PointCloud2>();
  output->header = input.header;
  output->header.stamp = toRosTime(reference);
  output->height = input.height;
  output->width = input.width;
  output->fields = input.fields;
  output->is_bigendian = input.is_bigendian;
  output->point_step = input.point_step;
  output->row_step = input.row_step;
  output->is_dense = input.is_dense;
  const Coordinates xyz(input);
  const CloudTimeField& time = prepared.time_field;
  // The time each corrected position holds: the reference, 0 from the new stamp.
  // (absolute: whole units and the fraction apart, as the drivers write them)
  double time_value = 0.0;
  if (time.absolute) {
    const auto unit_ns = static_cast<core::TimeNs>(std::llround(time.unit * 1e9));
    time_value = static_cast<double>(reference / unit_ns) +
                 static_cast<double>(reference % unit_ns) / static_cast<double>(unit_ns);
  }
  // A field that depends on x y z: Ouster's range.
  const PointField* const range =
      separateField(input, "range",
                    {&xyz.x, &xyz.y, &xyz.z, prepared.byAzimuth() ? nullptr : fieldNamed(input, time.name)});
  // A block of returns at a time: corrected into a buffer that stays in cache (with cloud_scan, into
  // corrected_, which the scan reads), their points' bytes copied from the input and overwritten while
  // they are in cache too: one pass over the input and one over the output, none over a buffer of every
  // corrected position. (Returns lie in increasing byte order, each within the data: checkCloudLayout.)
  constexpr std::size_t kBlock = 256;
  const std::size_t returns = prepared.points.size();
  const bool keep = params_.cloud_scan.enabled;
  corrected_.resize(keep ? returns : std::min(kBlock, returns));
  std::vector<std::uint8_t>& out = output->data;
  out.reserve(input.data.size());
  const std::uint8_t* const in = input.data.data();
  const std::uint32_t* const byte_offsets = prepared.byte_offsets.data();
  const Eigen::Vector3d* const raw = prepared.points.data();
  const std::uint32_t point_step = input.point_step;
  // write(byte_offsets, raw, corrected, count, data) writes a block, of the types dispatched once.
  const auto writeBlocks = [&](auto&& write) {
    for (std::size_t begin = 0; begin < returns; begin += kBlock) {
      const std::size_t end = std::min(begin + kBlock, returns);
      Eigen::Vector3d* const corrected = corrected_.data() + (keep ? begin : 0);
      deskewer_.correctFiringBlock(prepared.points, prepared.firings, begin, end, corrected);
      out.insert(out.end(), in + out.size(), in + byte_offsets[end - 1] + point_step);
      write(byte_offsets + begin, raw + begin, corrected, end - begin, out.data());
    }
  };
  xyz.withTypeAndPairing([&](auto coordinate, auto adjacent_xy) {
    using T = decltype(coordinate);
    constexpr bool kAdjacentXY = decltype(adjacent_xy)::value;
    if (range == nullptr) {
      if (prepared.byAzimuth()) {  // no field to rewrite
        writeBlocks([&](const std::uint32_t* offsets, const Eigen::Vector3d*, const Eigen::Vector3d* corrected,
                        std::size_t count, std::uint8_t* data) {
          writeReturns<T, kAdjacentXY, void>(xyz, 0, 0.0, offsets, corrected, count, data);
        });
        return;
      }
      withFieldType(time.datatype, [&](auto typed) {
        writeBlocks([&](const std::uint32_t* offsets, const Eigen::Vector3d*, const Eigen::Vector3d* corrected,
                        std::size_t count, std::uint8_t* data) {
          writeReturns<T, kAdjacentXY, decltype(typed)>(xyz, time.offset, time_value, offsets, corrected, count,
                                                        data);
        });
      });
      return;
    }
    withFieldType(range->datatype, [&](auto typed) {
      using R = decltype(typed);
      if constexpr (std::is_integral_v<R> && sizeof(R) == 4) {
        // A 4-byte time field (Ouster's uint32 t): written in the same loop, its value's bytes.
        if (!prepared.byAzimuth() && fieldSize(time.datatype) == 4) {
          std::uint32_t time_bits = 0;
          withFieldType(time.datatype, [&](auto time_typed) {
            using TimeType = decltype(time_typed);
            if constexpr (sizeof(TimeType) == sizeof time_bits) {
              const auto value = static_cast<TimeType>(time_value);
              std::memcpy(&time_bits, &value, sizeof time_bits);
            }
          });
          writeBlocks([&](const std::uint32_t* offsets, const Eigen::Vector3d* raw_points,
                          const Eigen::Vector3d* corrected, std::size_t count, std::uint8_t* data) {
            writeReturnsAndRanges<T, kAdjacentXY, R, true>(xyz, range->offset, offsets, raw_points, corrected, count,
                                                           data, time.offset, time_bits);
          });
          return;
        }
      }
      writeBlocks([&](const std::uint32_t* offsets, const Eigen::Vector3d* raw_points,
                      const Eigen::Vector3d* corrected, std::size_t count, std::uint8_t* data) {
        writeReturnsAndRanges<T, kAdjacentXY, R>(xyz, range->offset, offsets, raw_points, corrected, count, data);
        if (!prepared.byAzimuth()) {
          withFieldType(time.datatype, [&](auto time_typed) {
            writeTimes<decltype(time_typed)>(time.offset, time_value, offsets, count, data);
          });
        }
      });
    });
  });
  out.insert(out.end(), in + out.size(), in + input.data.size());  // past the last return
  CloudOutputs outputs;
  outputs.cloud = output;
  if (keep)
    outputs.scan = planarScan(corrected_, prepared, output->header);
  return outputs;
}

CloudOutputs CloudProcessor::passThrough(const PreparedCloud& prepared) const {
  CloudOutputs outputs;
  outputs.cloud = prepared.message;
  if (params_.cloud_scan.enabled)
    outputs.scan = planarScan(prepared.points, prepared, prepared.message->header);  // the raw points
  return outputs;
}

sensor_msgs::LaserScan::ConstPtr CloudProcessor::planarScan(const std::vector<Eigen::Vector3d>& points,
                                                            const PreparedCloud& prepared,
                                                            const std_msgs::Header& header) const {
  const DeskewParams::CloudScan& band = params_.cloud_scan;
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  scan->header = header;
  scan->angle_min = static_cast<float>(band.angle_min);
  scan->angle_increment = static_cast<float>(band.angle_increment);
  const auto bins =
      static_cast<std::size_t>(std::floor((band.angle_max - band.angle_min) / band.angle_increment)) + 1;
  scan->angle_max = static_cast<float>(band.angle_min + (bins - 1) * band.angle_increment);
  scan->time_increment = 0.0f;  // every point refers to the stamp
  scan->scan_time = 0.0f;
  scan->range_min = 0.0f;
  scan->range_max = static_cast<float>(band.range_max);
  scan->ranges.assign(bins, std::numeric_limits<float>::infinity());
  // The intensity of the point kept in each bin, when the cloud has an intensity field (0: no point).
  const sensor_msgs::PointCloud2& cloud = *prepared.message;
  const PointField* const intensity = separateField(cloud, "intensity", {});
  if (intensity != nullptr)
    scan->intensities.assign(bins, 0.0f);
  // A grid round the whole circle: the ray after the last bin is the first (+pi is -pi).
  const bool whole_circle =
      std::abs(static_cast<double>(bins) * band.angle_increment - 2.0 * M_PI) <= 0.5 * band.angle_increment;
  for (const Eigen::Vector3d& point : points) {
    if (!point.allFinite() || point.z() < band.height_min || point.z() > band.height_max)
      continue;
    const double range = std::hypot(point.x(), point.y());
    if (range > band.range_max || range == 0.0)
      continue;
    // The nearest point on each bin's ray (pointcloud_to_laserscan's rule, after the correction).
    double bin = std::round((std::atan2(point.y(), point.x()) - band.angle_min) / band.angle_increment);
    if (whole_circle && bin == static_cast<double>(bins))
      bin = 0.0;
    if (bin < 0.0 || bin >= static_cast<double>(bins))
      continue;
    const auto index = static_cast<std::size_t>(bin);
    if (static_cast<float>(range) >= scan->ranges[index])
      continue;
    scan->ranges[index] = static_cast<float>(range);
    if (intensity != nullptr) {
      const std::size_t point_index = static_cast<std::size_t>(&point - points.data());
      scan->intensities[index] = static_cast<float>(readNumber(
          &cloud.data[prepared.byte_offsets[point_index] + intensity->offset], intensity->datatype));
    }
  }
  return scan;
}

}  // namespace lidar_deskew::ros_adapter
