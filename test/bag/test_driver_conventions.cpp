// The 2D drivers' timing conventions (sim/drivers.h, docs/REAL_ROBOTS.md): a bag simulated as each
// driver writes its scans carries the header fields that driver's source writes (stamp against the
// true beam times, time_increment, scan_time, stated here from the sources' formulas, not from
// drivers.cpp), and deskew_calibrate finds the convention from a few seconds of a turning drive: the
// first beam's offset from the stamp within 1 ms and 2 sigma, the beam order exactly, the period
// within 0.5 % (estimated where the message's is wrong).
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <cmath>
#include <cstdio>
#include <iterator>
#include <ostream>
#include <stdexcept>

#include "lidar_deskew/bag/bag_calibrate.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/drivers.h"
#include "lidar_deskew/sim/sim_bag.h"
#include "support/temporary.h"

namespace lidar_deskew::sim {
namespace {

/// What the driver's source says, per driver (drivers.h names the files and lines).
struct Expected {
  LaserDriver driver;
  bool reversed;  ///< ranges written against the spin: the earliest beam is the last index
  /// [s] header.stamp - the earliest beam's true time, from the message's own fields
  double (*stamp_minus_first)(const sensor_msgs::LaserScan& scan, double period);
  /// [s] the time_increment the driver writes, from the message's fields and the true period
  double (*time_increment)(const sensor_msgs::LaserScan& scan, double period);
  double (*scan_time)(double period);  ///< [s]
  double drive = 4.0;                  ///< [s] of the turns drive simulated
};

double beams(const sensor_msgs::LaserScan& scan) {
  return static_cast<double>(scan.ranges.size());
}
double truePeriod(double period) {
  return period;
}
double zero(double) {
  return 0.0;
}
double atFirst(const sensor_msgs::LaserScan&, double) {
  return 0.0;
}
/// The latest beam: (n - 1) beams of the true beam period after the first.
double atLast(const sensor_msgs::LaserScan& scan, double period) {
  return (beams(scan) - 1.0) * period * std::abs(static_cast<double>(scan.angle_increment)) / (2.0 * M_PI);
}

const Expected kExpected[] = {
    // rplidar_ros: stamp before grabScanDataHq waits for the revolution; scan_time / (n - 1).
    {LaserDriver::kRplidar, true, atFirst,
     [](const sensor_msgs::LaserScan& scan, double) { return scan.scan_time / (beams(scan) - 1.0); },
     truePeriod},
    // urg_node: arrival after the last beam + (angle_min + pi) / 2pi x scan period; the sensor's increment.
    {LaserDriver::kUrgNode, false,
     [](const sensor_msgs::LaserScan& scan, double period) {
       return atLast(scan, period) + (scan.angle_min + M_PI) / (2.0 * M_PI) * period;
     },
     [](const sensor_msgs::LaserScan& scan, double period) {
       return period * std::abs(static_cast<double>(scan.angle_increment)) / (2.0 * M_PI);
     },
     truePeriod, 2.0},
    // sick_scan: the sensor's first-measurement time; 1 / measurement frequency.
    {LaserDriver::kSickScan, false, atFirst,
     [](const sensor_msgs::LaserScan& scan, double period) {
       return period * std::abs(static_cast<double>(scan.angle_increment)) / (2.0 * M_PI);
     },
     truePeriod},
    // hls_lfcd_lds_driver: now() after the revolution's bytes; 1 / (6 rpm), scan_time 360 x that.
    {LaserDriver::kHlsLfcdLds, true, atLast,
     [](const sensor_msgs::LaserScan&, double period) { return 1.0 / (6.0 * 60.0 / period); },
     [](double period) { return 360.0 / (6.0 * 60.0 / period); }},
    // ldlidar_stl_ros: now() when the revolution is complete; scan_time / (n - 1).
    {LaserDriver::kLdlidar, true, atLast,
     [](const sensor_msgs::LaserScan& scan, double) { return scan.scan_time / (beams(scan) - 1.0); },
     truePeriod},
    // ydlidar_ros_driver: the first point's time; scan_time / n.
    {LaserDriver::kYdlidar, true, atFirst,
     [](const sensor_msgs::LaserScan& scan, double) { return scan.scan_time / beams(scan); }, truePeriod},
    // xv_11_laser_driver: now() before poll() waits for the first packet; 64 rpm / 1e8; no scan_time.
    {LaserDriver::kXv11, false, atFirst,
     [](const sensor_msgs::LaserScan&, double period) { return 64.0 * (60.0 / period) / 1e8; }, zero},
    // ld08_driver (LDS-02): now() when the frame is ready; scan_time / ((angle_max - angle_min) / inc).
    {LaserDriver::kLd08, false, atLast,
     [](const sensor_msgs::LaserScan& scan, double) { return scan.scan_time / (beams(scan) - 1.0); },
     truePeriod},
};

void PrintTo(const Expected& expected, std::ostream* out) {
  *out << laserDriverName(expected.driver);
}

class DriverConventions : public testing::TestWithParam<Expected> {};

TEST_P(DriverConventions, MessagesAsTheDriverWritesThemAndCalibrateFindsTheConvention) {
  const Expected& expected = GetParam();
  const std::string name = laserDriverName(expected.driver);
  SCOPED_TRACE(name);
  Scenario scenario = driverScenario(expected.driver);
  scenario.duration = expected.drive;
  SimBagOptions options;
  options.noise = true;
  options.timing_fault = driverTiming(expected.driver, scenario.lidar);
  const std::string stem = test::temporary("driver", name);
  writeSimulationBag(scenario, options, stem + ".bag", stem + ".truth");
  const Truth truth = readTruth(stem + ".truth");
  const double period = 1.0 / scenario.lidar.rate;

  // The first scan (seq 0) as written: its earliest beam is truly at t = 0, the bag's epoch.
  sensor_msgs::LaserScan first;
  {
    rosbag::Bag bag(stem + ".bag");
    rosbag::View view(bag, rosbag::TopicQuery("/scan"));
    ASSERT_NE(view.begin(), view.end());
    first = *view.begin()->instantiate<sensor_msgs::LaserScan>();
  }
  ASSERT_EQ(first.header.seq, 0u);
  EXPECT_EQ(static_cast<int>(first.ranges.size()), scenario.lidar.beams);
  const double stamp_minus_first = (ros_adapter::toNs(first.header.stamp) - options.epoch) * 1e-9;
  EXPECT_NEAR(stamp_minus_first, expected.stamp_minus_first(first, period), 1e-6);
  EXPECT_NEAR(first.time_increment, expected.time_increment(first, period), 1e-9);
  EXPECT_NEAR(first.scan_time, expected.scan_time(period), 1e-6);
  EXPECT_EQ(truth.timing_fault.reversed, expected.reversed);

  // deskew_calibrate on the bag.
  bag::CalibrateOptions calibrate;
  calibrate.input = stem + ".bag";
  const bag::Calibration calibration = bag::calibrateBag(calibrate);
  const core::TimingEstimate& estimate = calibration.estimate;
  // One row of docs/REAL_ROBOTS.md's table (scripts/driver_conventions.sh collects them).
  std::printf("| %s | %.3f ms | %.3f ± %.3f ms | %s | %.3f ms (truth %.3f), %s |\n", name.c_str(),
              truth.timeOffset() * 1e3, estimate.time_offset * 1e3, estimate.offset_sigma * 1e3,
              estimate.timing.beam_order == core::BeamOrder::kReversed ? "reversed" : "as message",
              estimate.period * 1e3, period * 1e3, estimate.period_estimated ? "estimated" : "the message's");
  ASSERT_TRUE(estimate.told) << estimate.why;
  ASSERT_TRUE(estimate.offset_told) << estimate.why;
  const double offset_error = estimate.time_offset - truth.timeOffset();
  EXPECT_LE(std::abs(offset_error), 0.001);
  EXPECT_LE(std::abs(offset_error), 2.0 * estimate.offset_sigma);
  EXPECT_EQ(estimate.timing.beam_order == core::BeamOrder::kReversed, expected.reversed);
  // The message's period is kept when it is within 0.5 % of the truth, estimated otherwise.
  const double message_period = first.time_increment * 2.0 * M_PI / std::abs(first.angle_increment);
  EXPECT_EQ(estimate.period_estimated, std::abs(message_period / period - 1.0) > 0.005);
  EXPECT_NEAR(estimate.period, period, 0.005 * period);
  // What it writes: stamp_at end exactly for the drivers that stamp the latest beam; the first beam's
  // time under the written parameters within 1 ms of the truth.
  const bool stamped_at_latest =
      std::abs(truth.timing_fault.stamp_error - scenario.lidar.sweepDuration()) < 1e-9;
  EXPECT_EQ(estimate.timing.stamp_at == core::StampAt::kEnd, stamped_at_latest);
  const double written_offset =
      estimate.timing.time_offset - (estimate.timing.stamp_at == core::StampAt::kEnd ? estimate.sweep : 0.0);
  EXPECT_NEAR(written_offset, truth.timeOffset(), 0.001);
  std::remove((stem + ".bag").c_str());
  std::remove((stem + ".truth").c_str());
}

TEST(DriverNames, RoundTripAndBadInputNamed) {
  ASSERT_EQ(allLaserDrivers().size(), std::size(kExpected));  // every driver has its row above
  for (const LaserDriver driver : allLaserDrivers())
    EXPECT_EQ(laserDriverFromName(laserDriverName(driver)), driver);
  try {
    laserDriverFromName("rplidar_ros");
    ADD_FAILURE() << "an unknown name was taken";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("known: rplidar urg_node"), std::string::npos) << error.what();
  }
  LidarModel still = driverLidar(LaserDriver::kXv11);
  still.rate = 0.0;
  EXPECT_THROW(driverTiming(LaserDriver::kXv11, still), std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(EveryDriver, DriverConventions, testing::ValuesIn(kExpected),
                         [](const testing::TestParamInfo<Expected>& param_info) {
                           return laserDriverName(param_info.param.driver);
                         });

}  // namespace
}  // namespace lidar_deskew::sim
