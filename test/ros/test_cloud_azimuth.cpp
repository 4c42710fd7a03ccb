// Azimuth timing of clouds without a time field, against the simulator's true firing times: sweeps of
// the VLP-16 (clockwise) and the OS1-64 (counter-clockwise), mirrored for the other direction, in the
// drivers' layouts as the cloud holds them (float32), timed from the points' azimuth alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "lidar_deskew/core/types.h"
#include "lidar_deskew/ros/cloud_azimuth.h"
#include "lidar_deskew/ros/cloud_processor.h"
#include "lidar_deskew/ros/cloud_timing.h"
#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/text_params.h"
#include "lidar_deskew/sim/cloud_bag.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::azimuthOffsets;
using ros_adapter::AzimuthTiming;
using sim::CloudConvention;

constexpr double kUs = 1e-6;  // [s]

/// A sweep's points in firing order as the caller hands them over (NaN where no return) and each
/// point's true firing time [s] on the simulation clock.
struct Sweep {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> times;
  std::vector<int> rings;
  std::size_t points_per_column = 1;  ///< an organized cloud's height
};

/// One sweep of `sensor` ("VLP16" or "OS1-64") at high speed on an arc (6 m/s, 5 rad/s: the robot's own
/// turn must not leak into the times), written in `convention` and read back from the PointCloud2: an
/// organized cloud column by column.
Sweep sweepOf(const std::string& sensor, CloudConvention convention, double start_time = 0.3) {
  const sim::CloudScenario scenario = sim::findCloudScenario(sensor + "/high/arc");
  const sim::SimulatedCloud simulated = sim::simulateSweep(sim::World3::hall(), *scenario.trajectory(),
                                                           scenario.mount, scenario.lidar, start_time);
  const sensor_msgs::PointCloud2 cloud = sim::toPointCloud2(simulated, convention, 0, "lidar");
  Sweep sweep;
  sweep.points_per_column = cloud.height;
  const std::size_t count = simulated.points.size();
  const std::size_t height = cloud.height, width = cloud.width;
  for (std::size_t j = 0; j < count; ++j) {
    const std::size_t i = height > 1 ? (j % height) * width + j / height : j;  // column by column
    const std::uint8_t* point = &cloud.data[ros_adapter::pointOffset(cloud, i)];
    Eigen::Vector3d p;
    for (int axis = 0; axis < 3; ++axis)
      p[axis] = ros_adapter::readNumber(point + cloud.fields[axis].offset, cloud.fields[axis].datatype);
    if (!simulated.points[i].is_return)
      p.setConstant(std::numeric_limits<double>::quiet_NaN());
    sweep.points.push_back(p);
    sweep.times.push_back(simulated.points[i].time);
    sweep.rings.push_back(simulated.points[i].ring);
  }
  return sweep;
}

/// The same sweep seen in a mirror (y -> -y): it spins the other way.
Sweep mirrored(Sweep sweep) {
  for (Eigen::Vector3d& point : sweep.points)
    point.y() = -point.y();
  return sweep;
}

AzimuthTiming timingOf(const std::string& direction, const std::string& stamp_at, double period = 0.1) {
  AzimuthTiming timing;
  timing.enabled = true;
  timing.direction = direction;
  timing.stamp_at = stamp_at;
  timing.period = period;
  return timing;
}

struct Errors {
  double max = 0.0;  // [s]
  double rms = 0.0;  // [s]
  std::size_t points = 0;
};

/// The offsets from the azimuth against the true offsets from header.stamp (the first return's time
/// for start, the last's for end), over the points with an azimuth.
Errors errorsOf(const Sweep& sweep, const AzimuthTiming& timing) {
  std::vector<double> offsets;
  azimuthOffsets(sweep.points, timing, offsets, sweep.points_per_column);
  EXPECT_EQ(offsets.size(), sweep.points.size());
  double first = std::numeric_limits<double>::quiet_NaN(), last = first;
  for (std::size_t i = 0; i < sweep.points.size(); ++i) {
    if (!sweep.points[i].allFinite())
      continue;
    if (std::isnan(first))
      first = sweep.times[i];
    last = sweep.times[i];
  }
  const double stamp = timing.stamp_at == "end" ? last : first;
  Errors errors;
  double sum = 0.0;
  for (std::size_t i = 0; i < sweep.points.size(); ++i) {
    if (!sweep.points[i].allFinite())
      continue;
    const double error = offsets[i] - (sweep.times[i] - stamp);
    errors.max = std::max(errors.max, std::abs(error));
    sum += error * error;
    ++errors.points;
  }
  errors.rms = std::sqrt(sum / static_cast<double>(errors.points));
  return errors;
}

void expectNear(const std::vector<double>& offsets, const std::vector<double>& expected) {
  ASSERT_EQ(offsets.size(), expected.size());
  for (std::size_t i = 0; i < offsets.size(); ++i)
    EXPECT_NEAR(offsets[i], expected[i], 1e-12) << i;
}

void report(const char* what, const Errors& errors) {
  std::printf("%-52s %6zu points: offset error max %9.4f us, RMS %9.4f us\n", what, errors.points,
              errors.max / kUs, errors.rms / kUs);
}

// The simulator fires all rings of a column at the column's azimuth, so the azimuth tells the time up to
// the float32 coordinates' rounding: 2^-24 of the angle at worst, a few ns of a 0.1 s sweep. Both
// sensors, both spin directions (the mirror image spins the other way), header.stamp at either end.
TEST(CloudAzimuth, EverySweepIsTimedAsItWasFired) {
  const Sweep vlp16 = sweepOf("VLP16", CloudConvention::kNoTime);  // spins clockwise
  const Sweep os1 = sweepOf("OS1-64", CloudConvention::kOuster);   // counter-clockwise here
  ASSERT_EQ(vlp16.points.size(), 16u * 1800u);
  ASSERT_EQ(os1.points.size(), 64u * 1024u);
  struct Case {
    const char* name;
    const Sweep* sweep;
    bool mirror;
    const char* direction;
  };
  for (const Case& c : {Case{"VLP16", &vlp16, false, "cw"}, Case{"VLP16 mirrored", &vlp16, true, "ccw"},
                        Case{"OS1-64", &os1, false, "ccw"}, Case{"OS1-64 mirrored", &os1, true, "cw"}}) {
    const Sweep sweep = c.mirror ? mirrored(*c.sweep) : *c.sweep;
    for (const char* stamp_at : {"start", "end"}) {
      const Errors errors = errorsOf(sweep, timingOf(c.direction, stamp_at));
      report((std::string(c.name) + ", " + c.direction + ", stamp at " + stamp_at).c_str(), errors);
      EXPECT_LT(errors.max, 0.05 * kUs) << c.name << " " << stamp_at;
    }
    // The wrong direction is refused, not turned into times.
    const AzimuthTiming wrong = timingOf(std::string(c.direction) == "cw" ? "ccw" : "cw", "start");
    std::vector<double> offsets;
    try {
      azimuthOffsets(sweep.points, wrong, offsets);
      ADD_FAILURE() << c.name << ": the wrong direction was taken";
    } catch (const core::InvalidInput& error) {
      EXPECT_EQ(error.field(), "azimuth_direction") << error.what();
    }
  }
}

// Real beams do not share their column's azimuth: an OS1-64's beams sit up to about +-3.2 deg off it
// in a pattern repeating every 4 rings (OS1-64 Gen 1; a VLP-32C's +-4.2 deg likewise), and the cloud's
// coordinates carry the offset. Every point takes the time of its column's leading beam (firing order is
// time order), so none is a period late. Organized, by column: exact while a leading beam returns.
// Taken point by point (a dense cloud), the error is bounded by the offsets' spread over a revolution,
// 6.4 deg of 360 at 10 Hz = 1.78 ms, and reaches it when the first point is a trailing beam.
TEST(CloudAzimuth, BeamAzimuthOffsetsCostTheirSpreadAtMost) {
  const double offsets_deg[4] = {3.1, 1.0, -1.1, -3.3};
  const double spread = (3.1 + 3.3) / 360.0 * 0.1;  // [s]
  for (const int phase : {0, 3}) {                  // ring 0 leading (as the OS1-64 Gen 1's) or trailing
    for (const bool mirror : {false, true}) {
      Sweep sweep = sweepOf("OS1-64", CloudConvention::kOuster);
      for (std::size_t i = 0; i < sweep.points.size(); ++i) {  // ccw: a positive offset is ahead
        const double offset = offsets_deg[(sweep.rings[i] + phase) % 4] * M_PI / 180.0;
        sweep.points[i] = Eigen::AngleAxisd(offset, Eigen::Vector3d::UnitZ()) * sweep.points[i];
      }
      if (mirror)
        sweep = mirrored(sweep);
      const std::string direction = mirror ? "cw" : "ccw";
      for (const char* stamp_at : {"start", "end"}) {
        const std::string name = "OS1-64, beam offsets, ring 0 " +
                                 std::string(phase == 0 ? "leads" : "trails") + ", " + direction +
                                 ", stamp at " + stamp_at;
        const Errors by_column = errorsOf(sweep, timingOf(direction, stamp_at));
        report((name + ", by column").c_str(), by_column);
        EXPECT_LT(by_column.max, 0.05 * kUs) << name;
        Sweep dense = sweep;
        dense.points_per_column = 1;
        const Errors by_point = errorsOf(dense, timingOf(direction, stamp_at));
        report((name + ", by point").c_str(), by_point);
        EXPECT_LT(by_point.max, spread + 0.05 * kUs) << name;
        if (phase == 0 || std::string(stamp_at) == "end") {  // the first point leads, or the last counts
          EXPECT_LT(by_point.rms, 0.1 * spread) << name;
        }
      }
    }
  }
}

// A cloud that is part of a revolution (a driver's azimuth window, a cut packet) and one a little more
// than a revolution (drivers cut by packet count): the times go on past the period instead of wrapping.
TEST(CloudAzimuth, PartialAndLongerSweeps) {
  const Sweep full = sweepOf("VLP16", CloudConvention::kNoTime, 0.3);
  Sweep part = full;
  part.points.resize(full.points.size() * 2 / 5);  // 144 deg
  part.times.resize(part.points.size());
  Sweep longer = full;
  const Sweep next = sweepOf("VLP16", CloudConvention::kNoTime, 0.4);
  const std::size_t extra = next.points.size() / 20;  // 18 deg more: 378 deg
  longer.points.insert(longer.points.end(), next.points.begin(), next.points.begin() + extra);
  longer.times.insert(longer.times.end(), next.times.begin(), next.times.begin() + extra);
  for (const char* stamp_at : {"start", "end"}) {
    const Errors part_errors = errorsOf(part, timingOf("cw", stamp_at));
    report((std::string("VLP16, 144 deg of a sweep, stamp at ") + stamp_at).c_str(), part_errors);
    EXPECT_LT(part_errors.max, 0.05 * kUs);
    const Errors longer_errors = errorsOf(longer, timingOf("cw", stamp_at));
    report((std::string("VLP16, 378 deg, stamp at ") + stamp_at).c_str(), longer_errors);
    EXPECT_LT(longer_errors.max, 0.05 * kUs);
  }
  std::vector<double> offsets;
  azimuthOffsets(longer.points, timingOf("cw", "start"), offsets);
  EXPECT_NEAR(offsets.back(), 0.1 + 0.1 * (extra / 16 - 1) / 1800.0, 0.05 * kUs);  // past the period
}

// The rule at its limits, on hand-made points (ccw, 0.1 s, the first point at azimuth 0): up to 90 deg
// behind the furthest azimuth is a lagging beam (its time), beyond that it is ahead across a gap.
TEST(CloudAzimuth, StaggerWindowLimits) {
  const auto at = [](double degrees) {
    const double a = degrees * M_PI / 180.0;
    return Eigen::Vector3d(5.0 * std::cos(a), 5.0 * std::sin(a), 0.3);
  };
  const AzimuthTiming ccw = timingOf("ccw", "start");
  std::vector<double> offsets;
  azimuthOffsets({at(0), at(-2), at(10), at(-79), at(10.5)}, ccw, offsets);
  // -2 is just behind the start: the start's time, not 0.0994 s; -79 is 89 deg behind 10: 10's time.
  expectNear(offsets, {0.0, 0.0, 10.0 / 3600, 10.0 / 3600, 10.5 / 3600});
  // 91 deg behind 10 is 269 deg ahead (a gap; the points after it keep the net turn forward).
  azimuthOffsets({at(0), at(10), at(-81), at(-60), at(0)}, ccw, offsets);
  expectNear(offsets, {0.0, 10.0 / 3600, 279.0 / 3600, 300.0 / 3600, 360.0 / 3600});
  // Across the +-180 deg cut of atan2, and clockwise.
  azimuthOffsets({at(170), at(-170), at(-100)}, ccw, offsets);
  EXPECT_NEAR(offsets[1], 20.0 / 3600, 1e-12);
  EXPECT_NEAR(offsets[2], 90.0 / 3600, 1e-12);
  azimuthOffsets({at(-170), at(170), at(100)}, timingOf("cw", "end", 0.05), offsets);
  EXPECT_NEAR(offsets[0], -90.0 / 7200, 1e-12);
  EXPECT_NEAR(offsets[1], -70.0 / 7200, 1e-12);
  EXPECT_EQ(offsets[2], 0.0);
}

// Points without an azimuth (on the spin axis, within 1 cm of it, no-return markers: NaN or the origin)
// take the time of the point before them; the others are unaffected. None with an azimuth: all 0.
TEST(CloudAzimuth, PointsWithoutAnAzimuthTakeThePreviousTime) {
  const Sweep sweep = sweepOf("VLP16", CloudConvention::kNoTime);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Eigen::Vector3d> axis = {
      {0.0, 0.0, 2.0}, {0.006, -0.007, 1.5}, {nan, nan, nan}, {0.0, 0.0, 0.0}, {1.0, nan, 0.0}};
  std::vector<Eigen::Vector3d> points = sweep.points;
  const std::size_t middle = points.size() / 2;
  points.insert(points.begin() + middle, axis.begin(), axis.end());
  points.insert(points.begin(), axis.begin(), axis.end());
  for (const char* stamp_at : {"start", "end"}) {
    const AzimuthTiming timing = timingOf("cw", stamp_at);
    std::vector<double> offsets, clean;
    azimuthOffsets(points, timing, offsets);
    azimuthOffsets(sweep.points, timing, clean);
    ASSERT_EQ(offsets.size(), clean.size() + 2 * axis.size());
    for (std::size_t k = 0; k < axis.size(); ++k) {
      EXPECT_EQ(offsets[k], clean.front()) << k;  // before the first azimuth: the first point's time
      EXPECT_EQ(offsets[axis.size() + middle + k], clean[middle - 1]) << k;
    }
    for (std::size_t i = 0; i < clean.size(); ++i)
      ASSERT_EQ(offsets[i + axis.size() + (i >= middle ? axis.size() : 0)], clean[i]) << i;
  }
  std::vector<double> offsets = {7.0};
  azimuthOffsets(axis, timingOf("cw", "end"), offsets);
  EXPECT_EQ(offsets, std::vector<double>(axis.size(), 0.0));
  azimuthOffsets({}, timingOf("cw", "start"), offsets);
  EXPECT_TRUE(offsets.empty());
}

// Points out of firing order (a filter reordered them) cannot be timed by azimuth: refused, not guessed.
TEST(CloudAzimuth, PointsOutOfFiringOrderAreRefused) {
  Sweep sweep = sweepOf("VLP16", CloudConvention::kNoTime);
  std::mt19937 random(7);
  std::shuffle(sweep.points.begin(), sweep.points.end(), random);
  std::vector<double> offsets;
  try {
    azimuthOffsets(sweep.points, timingOf("cw", "start"), offsets);
    ADD_FAILURE() << "shuffled points were timed";
  } catch (const core::InvalidInput& error) {
    EXPECT_EQ(error.field(), "azimuth_timing") << error.what();
  }
}

TEST(CloudAzimuth, BadParametersAreNamed) {
  const auto fieldOf = [](const AzimuthTiming& timing) {
    try {
      std::vector<double> offsets;
      azimuthOffsets({{1.0, 0.0, 0.0}}, timing, offsets);
    } catch (const core::InvalidInput& error) {
      return error.field();
    }
    return std::string("accepted");
  };
  EXPECT_EQ(fieldOf(timingOf("cw", "start")), "accepted");
  EXPECT_EQ(fieldOf(timingOf("clockwise", "start")), "azimuth_direction");
  EXPECT_EQ(fieldOf(timingOf("cw", "middle")), "azimuth_stamp_at");
  for (const double period : {0.0, -0.1, 60.001, std::numeric_limits<double>::quiet_NaN()})
    EXPECT_EQ(fieldOf(timingOf("cw", "start", period)), "azimuth_period") << period;
  EXPECT_EQ(fieldOf(timingOf("cw", "start", 60.0)), "accepted");

  // As parameters: read, checked against their choices, and the period within a sweep's longest.
  using Values = std::map<std::string, std::string>;
  const auto load = [](const Values& values) {
    return ros_adapter::DeskewParams::load(ros_adapter::TextParams(values));
  };
  const ros_adapter::DeskewParams defaults = load({});
  EXPECT_FALSE(defaults.azimuth.enabled);  // never on by default
  EXPECT_EQ(defaults.azimuth.direction, "cw");
  EXPECT_EQ(defaults.azimuth.period, 0.1);
  EXPECT_EQ(defaults.azimuth.stamp_at, "start");
  const ros_adapter::DeskewParams set = load({{"azimuth_timing", "true"},
                                              {"azimuth_direction", "ccw"},
                                              {"azimuth_period", "0.05"},
                                              {"azimuth_stamp_at", "end"}});
  EXPECT_TRUE(set.azimuth.enabled);
  EXPECT_EQ(set.azimuth.direction, "ccw");
  EXPECT_EQ(set.azimuth.period, 0.05);
  EXPECT_EQ(set.azimuth.stamp_at, "end");
  for (const Values& bad :
       {Values{{"azimuth_direction", "up"}}, Values{{"azimuth_stamp_at", "middle"}},
        Values{{"azimuth_period", "0"}}, Values{{"azimuth_timing", "true"}, {"azimuth_period", "2"}}}) {
    try {
      load(bad);
      ADD_FAILURE() << bad.begin()->first << " accepted";
    } catch (const core::InvalidInput& error) {
      EXPECT_EQ(error.field().rfind("azimuth_", 0), 0u) << error.what();
      EXPECT_NE(error.field(), "azimuth_timing") << error.what();
    }
  }
  // A period beyond max_sweep_duration is harmless while the fallback is off.
  EXPECT_NO_THROW(load({{"azimuth_period", "2"}}));
}

// The case the fallback is for: the no_time layout has no time field, and without azimuth timing such
// a cloud is refused with its fields named.
TEST(CloudAzimuth, TheNoTimeLayoutHasNoTimeField) {
  const sim::CloudScenario scenario = sim::findCloudScenario("VLP16/normal/arc");
  const sensor_msgs::PointCloud2 cloud = sim::toPointCloud2(
      sim::simulateSweep(sim::World3::hall(), *scenario.trajectory(), scenario.mount, scenario.lidar, 0.0),
      CloudConvention::kNoTime, 1'700'000'000'000'000'000, "lidar");
  try {
    ros_adapter::findTimeField(cloud, ros_adapter::CloudTimeConfig());
    ADD_FAILURE() << "a time field was found";
  } catch (const core::InvalidInput& error) {
    EXPECT_NE(
        std::string(error.what()).find("x (float32), y (float32), z (float32), intensity (float32), ring"),
        std::string::npos)
        << error.what();
  }
}

// The wiring: CloudProcessor times a cloud that has no time field from its azimuth when azimuth_timing
// is set (a dense VLP-16 cloud as it is, an organized OS1-64 cloud column by column), and the times it
// gives are the ones the same cloud's own time field gives; without azimuth_timing it is refused.
TEST(CloudAzimuth, CloudProcessorTimesACloudWithoutTimeField) {
  constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;
  struct Case {
    const char* sensor;
    CloudConvention convention;
    const char* direction;
  };
  for (const Case& c : {Case{"VLP16", CloudConvention::kVelodyneFirst, "cw"},
                        Case{"OS1-64", CloudConvention::kOuster, "ccw"}}) {
    SCOPED_TRACE(c.sensor);
    const sim::CloudScenario scenario = sim::findCloudScenario(std::string(c.sensor) + "/high/arc");
    const auto timed = boost::make_shared<sensor_msgs::PointCloud2>(sim::toPointCloud2(
        sim::simulateSweep(sim::World3::hall(), *scenario.trajectory(), scenario.mount, scenario.lidar, 0.3),
        c.convention, kEpoch, "lidar"));
    ros_adapter::DeskewParams params;
    const ros_adapter::PreparedCloud by_field = ros_adapter::CloudProcessor(params).prepare(timed);
    ASSERT_FALSE(by_field.byAzimuth());
    auto untimed = boost::make_shared<sensor_msgs::PointCloud2>(*timed);
    for (sensor_msgs::PointField& field : untimed->fields) {
      if (field.name == by_field.time_field.name)
        field.name = "unused";
    }
    EXPECT_THROW(ros_adapter::CloudProcessor(params).prepare(untimed), core::InvalidInput);
    params.azimuth = timingOf(c.direction, "start");
    const ros_adapter::PreparedCloud by_azimuth = ros_adapter::CloudProcessor(params).prepare(untimed);
    EXPECT_TRUE(by_azimuth.byAzimuth());
    EXPECT_NE(by_azimuth.timingFallback(), nullptr);
    ASSERT_EQ(by_azimuth.points.size(), by_field.points.size());
    core::TimeNs worst = 0;
    for (std::size_t i = 0; i < by_field.points.size(); ++i)
      worst = std::max(worst, std::abs(by_azimuth.timeOf(i) - by_field.timeOf(i)));
    std::printf("%s: %zu returns timed by azimuth, at most %.3f us from the time field's times\n", c.sensor,
                by_field.points.size(), 1e-3 * static_cast<double>(worst));
    EXPECT_LE(worst, 1000);  // [ns]
    EXPECT_EQ(by_azimuth.first, by_field.first);
  }
}

}  // namespace
}  // namespace lidar_deskew::test
