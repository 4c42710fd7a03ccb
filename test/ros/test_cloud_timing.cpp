// Per-point times of PointCloud2s in each common driver's convention, found with no configuration:
// the decided field, unit and base, and every point's time against the time it was written from.
#include <gtest/gtest.h>
#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "lidar_deskew/ros/cloud_timing.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/range_scaling.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::CloudTimeConfig;
using ros_adapter::CloudTimeField;
using sensor_msgs::PointField;

constexpr core::TimeNs kSweepStart = 1'700'000'123'456'789'000;  // [ns]
constexpr double kSweep = 0.1;                                   // [s] first to last point
constexpr std::size_t kPoints = 1000;

/// The true time of point i [ns]: evenly over the sweep.
core::TimeNs trueTime(std::size_t i) {
  return kSweepStart + core::secondsToNs(kSweep * static_cast<double>(i) / (kPoints - 1));
}

/// A cloud of kPoints with x y z float32 and one time field of `datatype`, whose value for point i
/// is `value(i)`, stamped `stamp`.
sensor_msgs::PointCloud2 cloudWith(const std::string& name, std::uint8_t datatype, core::TimeNs stamp,
                                   const std::function<double(std::size_t)>& value) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header.stamp = ros_adapter::toRosTime(stamp);
  cloud.header.frame_id = "lidar";
  for (const char* axis : {"x", "y", "z"}) {
    PointField field;
    field.name = axis;
    field.offset = static_cast<std::uint32_t>(4 * cloud.fields.size());
    field.datatype = PointField::FLOAT32;
    field.count = 1;
    cloud.fields.push_back(field);
  }
  PointField time;
  time.name = name;
  time.offset = 16;  // padded, as drivers do
  time.datatype = datatype;
  time.count = 1;
  cloud.fields.push_back(time);
  cloud.point_step = 16 + 8;
  cloud.width = kPoints;
  cloud.height = 1;
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.data.assign(cloud.row_step, 0);
  for (std::size_t i = 0; i < kPoints; ++i) {
    std::uint8_t* point = &cloud.data[i * cloud.point_step];
    const float xyz[3] = {1.0f, 2.0f, 0.5f};
    std::memcpy(point, xyz, sizeof xyz);
    const double v = value(i);
    switch (datatype) {
      case PointField::UINT32: {
        const auto typed = static_cast<std::uint32_t>(std::llround(v));
        std::memcpy(point + 16, &typed, sizeof typed);
        break;
      }
      case PointField::FLOAT32: {
        const auto typed = static_cast<float>(v);
        std::memcpy(point + 16, &typed, sizeof typed);
        break;
      }
      case PointField::FLOAT64:
        std::memcpy(point + 16, &v, sizeof v);
        break;
      default:
        ADD_FAILURE() << "type not written by this test";
    }
  }
  return cloud;
}

struct Case {
  const char* driver;
  const char* field;
  std::uint8_t datatype;
  core::TimeNs stamp;  // header.stamp as the driver sets it
  std::function<double(std::size_t)> value;
  bool absolute;
  double unit;
  double tolerance;  // [ns] of the decoded times (float32 seconds keep ~8 ns at 0.1 s)
};

/// A time as drivers write it in float64 seconds: whole seconds plus the fraction (to the double
/// nearest, about 0.1 us at epoch-sized times).
double absoluteSeconds(core::TimeNs time) {
  return static_cast<double>(time / 1'000'000'000) + static_cast<double>(time % 1'000'000'000) * 1e-9;
}

double relativeSeconds(std::size_t i, core::TimeNs stamp) {
  return core::nsToSeconds(trueTime(i) - stamp);
}

TEST(CloudTiming, EveryCommonDriverConventionIsFoundAlone) {
  const core::TimeNs last = trueTime(kPoints - 1);
  const std::vector<Case> cases = {
      {"Ouster", "t", PointField::UINT32, kSweepStart,
       [](std::size_t i) { return static_cast<double>(trueTime(i) - kSweepStart); }, false, 1e-9, 0},
      {"Velodyne (first packet)", "time", PointField::FLOAT32, kSweepStart,
       [](std::size_t i) { return relativeSeconds(i, kSweepStart); }, false, 1.0, 10},
      {"Velodyne (last packet)", "time", PointField::FLOAT32, last,
       [last](std::size_t i) { return relativeSeconds(i, last); }, false, 1.0, 10},
      {"Hesai", "timestamp", PointField::FLOAT64, kSweepStart,
       [](std::size_t i) { return absoluteSeconds(trueTime(i)); }, true, 1.0, 150},
      {"RoboSense (stamp at the last point)", "timestamp", PointField::FLOAT64, last,
       [](std::size_t i) { return absoluteSeconds(trueTime(i)); }, true, 1.0, 150},
      {"Livox ROS driver 2", "timestamp", PointField::FLOAT64, kSweepStart,
       [](std::size_t i) { return static_cast<double>(trueTime(i)); }, true, 1e-9, 300},
      {"Autoware", "time_stamp", PointField::UINT32, kSweepStart,
       [](std::size_t i) { return static_cast<double>(trueTime(i) - kSweepStart); }, false, 1e-9, 0},
      {"Livox custom", "offset_time", PointField::UINT32, kSweepStart,
       [](std::size_t i) { return static_cast<double>(trueTime(i) - kSweepStart); }, false, 1e-9, 0},
      {"laser_geometry", "stamps", PointField::FLOAT32, kSweepStart,
       [](std::size_t i) { return relativeSeconds(i, kSweepStart); }, false, 1.0, 10},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.driver);
    const sensor_msgs::PointCloud2 cloud = cloudWith(c.field, c.datatype, c.stamp, c.value);
    ros_adapter::checkCloudLayout(cloud);
    const CloudTimeField found = ros_adapter::findTimeField(cloud, CloudTimeConfig());
    EXPECT_EQ(found.name, c.field);
    EXPECT_EQ(found.absolute, c.absolute) << found.describe();
    EXPECT_EQ(found.unit, c.unit) << found.describe();
    std::vector<core::TimeNs> times;
    ros_adapter::pointTimes(cloud, found, times);
    ASSERT_EQ(times.size(), kPoints);
    core::TimeNs worst = 0;
    for (std::size_t i = 0; i < kPoints; ++i)
      worst = std::max(worst, std::abs(times[i] - trueTime(i)));
    EXPECT_LE(worst, c.tolerance + 1) << found.describe();
  }
}

// A short cloud (a packet, a narrow window): integer ns stay ns and float s stay s, never 1000 x too long.
TEST(CloudTiming, ShortCloudsKeepTheDriversUnit) {
  const auto span = [](const sensor_msgs::PointCloud2& cloud, const CloudTimeField& field) {
    std::vector<core::TimeNs> times;
    ros_adapter::pointTimes(cloud, field, times);
    return core::nsToSeconds(*std::max_element(times.begin(), times.end()) -
                             *std::min_element(times.begin(), times.end()));
  };
  const sensor_msgs::PointCloud2 ns =
      cloudWith("t", PointField::UINT32, kSweepStart, [](std::size_t i) { return 500.0 * i; });  // 0.5 ms
  EXPECT_EQ(ros_adapter::findTimeField(ns, CloudTimeConfig()).unit, 1e-9);
  EXPECT_NEAR(span(ns, ros_adapter::findTimeField(ns, CloudTimeConfig())), 0.4995e-3, 1e-9);
  const sensor_msgs::PointCloud2 s = cloudWith("time", PointField::FLOAT32, kSweepStart,
                                               [](std::size_t i) { return 0.5e-6 * i; });  // 0.5 ms
  EXPECT_EQ(ros_adapter::findTimeField(s, CloudTimeConfig()).unit, 1.0);
}

// Near time 0 (a simulator's clock) offsets and absolute times look alike: offsets win.
TEST(CloudTiming, OffsetsNearTimeZeroAreOffsets) {
  const core::TimeNs stamp = 500'000'000;  // 0.5 s into the simulation
  const sensor_msgs::PointCloud2 cloud = cloudWith("time", PointField::FLOAT32, stamp, [](std::size_t i) {
    return kSweep * static_cast<double>(i) / (kPoints - 1);
  });
  const CloudTimeField found = ros_adapter::findTimeField(cloud, CloudTimeConfig());
  EXPECT_FALSE(found.absolute);
  std::vector<core::TimeNs> times;
  ros_adapter::pointTimes(cloud, found, times);
  EXPECT_EQ(times.front(), stamp);
}

// No-return points may carry any time, or none: only the returns' times count.
TEST(CloudTiming, NoReturnPointsDoNotDecide) {
  sensor_msgs::PointCloud2 cloud =
      cloudWith("timestamp", PointField::FLOAT64, kSweepStart, [](std::size_t i) {
        return i % 10 == 0 ? (i % 20 == 0 ? 0.0 : NAN) : absoluteSeconds(trueTime(i));  // zero-filled and NaN
      });
  std::vector<bool> returns(kPoints);
  for (std::size_t i = 0; i < kPoints; ++i)
    returns[i] = i % 10 != 0;
  EXPECT_THROW(ros_adapter::findTimeField(cloud, CloudTimeConfig()), core::InvalidInput);  // NaN, all counted
  const CloudTimeField found = ros_adapter::findTimeField(cloud, CloudTimeConfig(), &returns);
  EXPECT_TRUE(found.absolute);
  std::vector<core::TimeNs> times;
  ros_adapter::pointTimes(cloud, found, times, &returns);
  for (std::size_t i = 1; i < kPoints; i += 10)
    EXPECT_LE(std::abs(times[i] - trueTime(i)), 150);
}

TEST(CloudTiming, ParametersOverrideTheDecision) {
  // Offsets in ms that would pass for a (short) sweep in s: the unit given wins.
  const sensor_msgs::PointCloud2 cloud =
      cloudWith("time", PointField::FLOAT32, kSweepStart, [](std::size_t i) {
        return 1e3 * relativeSeconds(i, kSweepStart) * 0.005;  // 0 .. 0.5 "ms"
      });
  CloudTimeConfig config;
  EXPECT_EQ(ros_adapter::findTimeField(cloud, config).unit, 1.0);
  config.unit = "ms";
  EXPECT_EQ(ros_adapter::findTimeField(cloud, config).unit, 1e-3);
  // A field of another name, named.
  const sensor_msgs::PointCloud2 other =
      cloudWith("point_time", PointField::FLOAT32, kSweepStart,
                [](std::size_t i) { return relativeSeconds(i, kSweepStart); });
  config = CloudTimeConfig();
  EXPECT_THROW(ros_adapter::findTimeField(other, config), core::InvalidInput);
  config.field = "point_time";
  EXPECT_EQ(ros_adapter::findTimeField(other, config).name, "point_time");
  config.unit = "minutes";
  EXPECT_THROW(config.validate(), core::InvalidInput);
  // Integer microseconds (no common driver): taken as ns alone, as us when told.
  const sensor_msgs::PointCloud2 us = cloudWith("t", PointField::UINT32, kSweepStart, [](std::size_t i) {
    return 1e-3 * static_cast<double>(trueTime(i) - kSweepStart);
  });
  EXPECT_EQ(ros_adapter::findTimeField(us, CloudTimeConfig()).unit, 1e-9);
  config = CloudTimeConfig();
  config.unit = "us";
  EXPECT_EQ(ros_adapter::findTimeField(us, config).unit, 1e-6);
  // Both given decide, whatever the values: absolute stamps 10 s off the header (an unsynchronised clock).
  const sensor_msgs::PointCloud2 skewed =
      cloudWith("timestamp", PointField::FLOAT64, kSweepStart,
                [](std::size_t i) { return absoluteSeconds(trueTime(i)) + 10.0; });
  EXPECT_THROW(ros_adapter::findTimeField(skewed, CloudTimeConfig()), core::InvalidInput);
  config.unit = "s";
  config.base = "absolute";
  EXPECT_TRUE(ros_adapter::findTimeField(skewed, config).absolute);
}

TEST(CloudTiming, NoTimeFieldIsAnErrorNamingTheCloudsFields) {
  sensor_msgs::PointCloud2 cloud =
      cloudWith("intensity", PointField::FLOAT32, kSweepStart, [](std::size_t) { return 7.0; });
  try {
    ros_adapter::findTimeField(cloud, CloudTimeConfig());
    ADD_FAILURE() << "found a time field";
  } catch (const core::InvalidInput& error) {
    const std::string text = error.what();
    EXPECT_NE(text.find("x (float32), y (float32), z (float32), intensity (float32)"), std::string::npos)
        << text;
  }
  // Values that are no sweep in any unit near the header: refused, not guessed.
  cloud = cloudWith("time", PointField::FLOAT64, kSweepStart, [](std::size_t i) { return 1e7 * i; });
  EXPECT_THROW(ros_adapter::findTimeField(cloud, CloudTimeConfig()), core::InvalidInput);
}

TEST(CloudTiming, BadLayoutsAreRefusedNamingTheField) {
  sensor_msgs::PointCloud2 cloud =
      cloudWith("t", PointField::UINT32, kSweepStart, [](std::size_t) { return 0.0; });
  cloud.data.resize(cloud.data.size() - 1);
  try {
    ros_adapter::checkCloudLayout(cloud);
    ADD_FAILURE();
  } catch (const core::InvalidInput& error) {
    EXPECT_EQ(error.field(), "data");
  }
  cloud = cloudWith("t", PointField::UINT32, kSweepStart, [](std::size_t) { return 0.0; });
  cloud.fields.back().offset = cloud.point_step - 2;
  EXPECT_THROW(ros_adapter::checkCloudLayout(cloud), core::InvalidInput);
  cloud = cloudWith("t", PointField::UINT32, kSweepStart, [](std::size_t) { return 0.0; });
  cloud.row_step = 4;
  EXPECT_THROW(ros_adapter::checkCloudLayout(cloud), core::InvalidInput);
}

/// toFieldValue (the range field's conversion, inline) against std::round and std::clamp: every integer
/// type over values at and next to every half, the types' bounds, big and random values; floating types
/// clamped only.
template <typename T>
std::size_t fieldValueMismatches(const std::vector<double>& values) {
  constexpr double lowest = static_cast<double>(std::numeric_limits<T>::lowest());
  constexpr double highest = static_cast<double>(std::numeric_limits<T>::max());
  std::size_t mismatches = 0;
  for (const double value : values) {
    const double expected = std::is_integral_v<T> ? std::round(value) : value;
    const T truth = static_cast<T>(std::clamp(expected, lowest, highest));
    const T ours = ros_adapter::toFieldValue<T>(value);
    if (std::memcmp(&truth, &ours, sizeof(T)) != 0)
      ++mismatches;
  }
  return mismatches;
}

/// Values at and next to every half, the integer types' bounds, big and random values.
std::vector<double> roundingCases() {
  using limits = std::numeric_limits<double>;
  std::vector<double> values;
  for (const double special : {0.0, 0.49999999999999994, 4503599627370495.5, 4503599627370497.0, 1e300,
                               limits::denorm_min(), limits::max()}) {
    values.push_back(special);
    values.push_back(-special);
  }
  const auto around = [&values](double centre) {
    values.push_back(centre);
    values.push_back(std::nextafter(centre, -HUGE_VAL));
    values.push_back(std::nextafter(centre, HUGE_VAL));
  };
  for (const double bound : {128.0, 256.0, 32768.0, 65536.0, 2147483648.0, 4294967296.0}) {
    for (const double edge :
         {bound, -bound, bound - 1.0, -bound - 1.0, bound - 0.5, -bound + 0.5, -bound - 0.5, bound + 0.5})
      around(edge);
  }
  for (int k = -3000; k <= 3000; ++k) {
    around(k + 0.5);
    around(k * 137.0 + 0.5);  // halves of larger values too
    around(k * 1'431'655.0 + 0.5);
  }
  std::mt19937_64 random(25);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 200'000; ++i)
    values.push_back(unit(random) * std::pow(2.0, static_cast<double>(i % 40)));
  return values;
}

TEST(CloudTiming, FieldValuesAreRoundedAndClampedAsStdRoundDoes) {
  const std::vector<double> values = roundingCases();
  for (std::uint8_t datatype = PointField::INT8; datatype <= PointField::FLOAT64; ++datatype) {
    ros_adapter::withFieldType(datatype, [&](auto typed) {
      EXPECT_EQ(fieldValueMismatches<decltype(typed)>(values), 0u) << "datatype " << static_cast<int>(datatype);
    });
  }
  // The test can fail: truncation alone, the conversion this replaces a libm call with, differs.
  std::size_t truncated_differ = 0;
  for (const double value : values)
    truncated_differ += std::abs(value) < 1e9 && std::trunc(value) != std::round(value);
  EXPECT_GT(truncated_differ, 10'000u);
}

/// toFieldValues (two at a time: SSE2 on x86-64) against toFieldValue one value at a time, each value
/// paired with the next and with the one before (either lane).
template <typename T>
std::size_t pairMismatches(const std::vector<double>& values) {
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i + 1 < values.size(); ++i) {
    T first, second;
    ros_adapter::toFieldValues<T>(values[i], values[i + 1], first, second);
    const T truth_first = ros_adapter::toFieldValue<T>(values[i]);
    const T truth_second = ros_adapter::toFieldValue<T>(values[i + 1]);
    mismatches += std::memcmp(&first, &truth_first, sizeof(T)) != 0;
    mismatches += std::memcmp(&second, &truth_second, sizeof(T)) != 0;
  }
  return mismatches;
}

TEST(CloudTiming, PairsOfFieldValuesAreConvertedAsOneAtATime) {
  const std::vector<double> values = roundingCases();
  for (std::uint8_t datatype = PointField::INT8; datatype <= PointField::FLOAT64; ++datatype) {
    ros_adapter::withFieldType(datatype, [&](auto typed) {
      EXPECT_EQ(pairMismatches<decltype(typed)>(values), 0u) << "datatype " << static_cast<int>(datatype);
    });
  }
}

#if defined(__SSE2__)
// The range field's float estimates (CloudProcessor, a 32-bit integer range) against the exact scaled
// range, value x sqrt(corrected^2) / sqrt(raw^2) in doubles rounded as toFieldValue does (uint32 and
// int32): where an estimate says it is sure it must equal that, over ranges of 0.5-120 m in mm moved
// up to 5 %, values whose scaled range lies within 1e-6 of a half (sure there would be a guess), big
// values, values beyond int32 (negative in its lanes), and squares that are 0, tiny, huge or not finite.
TEST(CloudTiming, RangeEstimatesAreSureOnlyOfTheExactRoundedValue) {
  std::mt19937_64 random(35);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double specials[] = {0.0, 1e-200, 1e-40, 1e40, 1e200, HUGE_VAL, std::numeric_limits<double>::quiet_NaN()};
  std::size_t mismatches = 0, typical = 0, typical_sure = 0, halves = 0, halves_sure = 0, big = 0, big_sure = 0,
              out_of_range_sure = 0;
  for (int n = 0; n < 200'000; ++n) {
    std::uint32_t values[4];
    double corrected[4], raw[4];
    const int kind = n % 4;
    for (int i = 0; i < 4; ++i) {
      const double distance = 500.0 + unit(random) * 119'500.0;  // [mm]
      raw[i] = distance * distance * 1e-6;                        // [m^2]
      const double ratio = 0.95 + 0.1 * unit(random);
      values[i] = static_cast<std::uint32_t>(std::lround(distance));
      if (kind == 1) {  // the exact scaled range within 1e-6 of a half
        const double half = std::floor(distance * ratio) + 0.5 + (unit(random) - 0.5) * 2e-6;
        corrected[i] = raw[i] * (half / values[i]) * (half / values[i]);
      } else {
        corrected[i] = raw[i] * ratio * ratio;
      }
      if (kind == 2)  // big values, and beyond int32
        values[i] = static_cast<std::uint32_t>(unit(random) * 4294967295.0);
      if (kind == 3) {  // squares out of range
        (i % 2 == 0 ? corrected[i] : raw[i]) = specials[random() % std::size(specials)];
      }
    }
    const ros_adapter::RangeEstimates estimates = ros_adapter::estimateRanges(
        _mm_setr_epi32(static_cast<int>(values[0]), static_cast<int>(values[1]), static_cast<int>(values[2]),
                       static_cast<int>(values[3])),
        _mm_setr_pd(corrected[0], corrected[1]), _mm_setr_pd(corrected[2], corrected[3]), _mm_setr_pd(raw[0], raw[1]),
        _mm_setr_pd(raw[2], raw[3]));
    alignas(16) std::int32_t rounded[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(rounded), estimates.rounded);
    for (int i = 0; i < 4; ++i) {
      const bool sure = (estimates.sure >> i & 1) != 0;
      typical += kind == 0;
      typical_sure += kind == 0 && sure;
      halves += kind == 1;
      halves_sure += kind == 1 && sure;
      big += kind == 2;
      big_sure += kind == 2 && sure;
      out_of_range_sure += kind == 3 && sure;
      if (!sure)
        continue;
      const double as_uint32 = static_cast<double>(values[i]) * std::sqrt(corrected[i]) / std::sqrt(raw[i]);
      const double as_int32 =
          static_cast<double>(static_cast<std::int32_t>(values[i])) * std::sqrt(corrected[i]) / std::sqrt(raw[i]);
      mismatches += !std::isfinite(as_uint32) || !std::isfinite(as_int32) ||
                    ros_adapter::toFieldValue<std::uint32_t>(as_uint32) != static_cast<std::uint32_t>(rounded[i]) ||
                    ros_adapter::toFieldValue<std::int32_t>(as_int32) != rounded[i];
    }
  }
  EXPECT_EQ(mismatches, 0u);
  // Sure of most typical ranges (at 60 m, all but those within 0.03 mm of a half: 94 %), of hardly any
  // near a half, of big values only below 2^22 (0.1 %), never with a square out of [2^-60, 2^60].
  EXPECT_GT(typical_sure, typical * 90 / 100) << typical_sure << " of " << typical;
  EXPECT_LT(halves_sure, halves / 100) << halves_sure << " of " << halves;
  EXPECT_GT(big_sure, 20u);
  EXPECT_LT(big_sure, big / 200) << big_sure << " of " << big;
  EXPECT_EQ(out_of_range_sure, 0u);
}
#endif

}  // namespace
}  // namespace lidar_deskew::test
