// Simulated LaserScan bags with timing faults read back with the rosbag C++ API: every /scan carries
// the faulted stamp, time_increment and scan_time over the truly measured ranges (those of
// simulateScan with the same fault), record times never precede stamps, odometry covers the beam
// times both as true and as claimed, and the truth file holds the fault and the true periods.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lidar_deskew/sim/sim_bag.h"

namespace lidar_deskew::sim {
namespace {

struct Recorded {
  std::vector<sensor_msgs::LaserScan> scans;
  std::vector<core::TimeNs> scan_record_times;
  std::vector<core::TimeNs> tf_times;      // [ns] stamps of odom -> base_link
  std::vector<core::TimeNs> record_times;  // of every message, in file order
};

Recorded readBag(const std::string& path) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  Recorded recorded;
  for (const rosbag::MessageInstance& message : rosbag::View(bag)) {
    recorded.record_times.push_back(static_cast<core::TimeNs>(message.getTime().toNSec()));
    if (message.getTopic() == "/scan") {
      recorded.scans.push_back(*message.instantiate<sensor_msgs::LaserScan>());
      recorded.scan_record_times.push_back(static_cast<core::TimeNs>(message.getTime().toNSec()));
    } else if (message.getTopic() == "/tf") {
      const tf2_msgs::TFMessage::ConstPtr transforms = message.instantiate<tf2_msgs::TFMessage>();
      for (const auto& transform : transforms->transforms)
        recorded.tf_times.push_back(static_cast<core::TimeNs>(transform.header.stamp.toNSec()));
    }
  }
  return recorded;
}

/// Writes `scenario` (1 s of it) with `fault` and checks the bag and truth against simulateScan.
void checkFaultedBag(Scenario scenario, const TimingFault& fault, const std::string& label) {
  SCOPED_TRACE(label);
  // One second of it, without the standing start: every scan moves.
  scenario.pieces.erase(scenario.pieces.begin());
  scenario.duration = 1.0;
  SimBagOptions options;
  options.timing_fault = fault;
  const std::string bag_path = ::testing::TempDir() + "/sim_" + label + ".bag";
  const std::string truth_path = ::testing::TempDir() + "/sim_" + label + ".truth";
  writeSimulationBag(scenario, options, bag_path, truth_path);
  const Recorded recorded = readBag(bag_path);

  const LidarModel& model = scenario.lidar;
  const double period = 1.0 / model.rate;
  const double dt = static_cast<double>(model.timeIncrement());
  const std::size_t n = static_cast<std::size_t>(model.beams);
  ASSERT_EQ(recorded.scans.size(), static_cast<std::size_t>(std::lround(scenario.duration * model.rate)));
  const PiecewiseTrajectory trajectory = scenario.trajectory();
  core::TimeNs earliest_claimed = 0, latest_claimed = 0;
  for (std::size_t k = 0; k < recorded.scans.size(); ++k) {
    const sensor_msgs::LaserScan& scan = recorded.scans[k];
    const SimulatedScan expected = simulateScan(scenario.world, trajectory, scenario.mount, model,
                                                options.epoch, k * period, nullptr, fault);
    // stamp = true earliest beam + stamp_error
    const double earliest = *std::min_element(expected.beam_times.begin(), expected.beam_times.end());
    EXPECT_NEAR(k * period, earliest, 1e-12);
    const core::TimeNs stamp = static_cast<core::TimeNs>(scan.header.stamp.toNSec());
    EXPECT_EQ(stamp, options.epoch + core::secondsToNs(k * period) + core::secondsToNs(fault.stamp_error))
        << k;
    EXPECT_EQ(scan.time_increment, static_cast<float>(fault.time_increment_factor * dt));
    EXPECT_EQ(scan.scan_time, fault.zero_scan_time ? 0.0f : static_cast<float>(period));
    EXPECT_GT(scan.angle_increment, 0.0f);
    EXPECT_EQ(scan.ranges, expected.scan.ranges) << k;
    // Recorded once the sweep is over, and not before its stamp.
    EXPECT_GE(recorded.scan_record_times[k], stamp);
    EXPECT_GE(recorded.scan_record_times[k], options.epoch + core::secondsToNs((k + 1) * period));
    const core::TimeNs claimed_end =
        stamp + core::secondsToNs((n - 1) * static_cast<double>(scan.time_increment));
    if (k == 0)
      earliest_claimed = std::min(stamp, options.epoch);
    latest_claimed =
        std::max({latest_claimed, claimed_end, options.epoch + core::secondsToNs(k * period + period)});
  }
  // Odometry covers the claimed and the true beam times with tf_margin on both sides, on 50 Hz samples.
  ASSERT_FALSE(recorded.tf_times.empty());
  EXPECT_LE(recorded.tf_times.front(), earliest_claimed - core::secondsToNs(options.tf_margin));
  EXPECT_GE(recorded.tf_times.back(), latest_claimed + core::secondsToNs(options.tf_margin) - 20'000'000);
  for (const core::TimeNs time : recorded.tf_times)
    EXPECT_EQ((time - options.epoch) % 20'000'000, 0) << time - options.epoch;
  // Written in time order, as a recorder writes.
  EXPECT_TRUE(std::is_sorted(recorded.record_times.begin(), recorded.record_times.end()));

  const Truth truth = readTruth(truth_path);
  EXPECT_EQ(truth.scenario, scenario.name);
  EXPECT_EQ(truth.timing_fault.stamp_error, fault.stamp_error);
  EXPECT_EQ(truth.timeOffset(), -fault.stamp_error);
  EXPECT_EQ(truth.timing_fault.reversed, fault.reversed);
  EXPECT_EQ(truth.timing_fault.time_increment_factor, fault.time_increment_factor);
  EXPECT_EQ(truth.timing_fault.zero_scan_time, fault.zero_scan_time);
  EXPECT_EQ(truth.beam_period, dt);
  EXPECT_EQ(truth.sweep_period, period);
  EXPECT_EQ(truth.world.segments().size(), scenario.world.segments().size());
  // The truth tells every beam's true time from the message's stamp.
  const sensor_msgs::LaserScan& last = recorded.scans.back();
  const SimulatedScan expected =
      simulateScan(scenario.world, trajectory, scenario.mount, model, options.epoch,
                   (recorded.scans.size() - 1) * period, nullptr, fault);
  for (std::size_t i = 0; i < n; i += 17) {
    EXPECT_NEAR(
        core::nsToSeconds(truth.beamTime(static_cast<core::TimeNs>(last.header.stamp.toNSec()), i, n) -
                          options.epoch),
        expected.beam_times[i], 2e-9);
  }
  std::remove(bag_path.c_str());
  std::remove(truth_path.c_str());
}

TEST(SimBag, NoFault) {
  checkFaultedBag(findScenario("LDS-01/normal/turns"), TimingFault(), "none");
}

TEST(SimBag, StampedLateAndReversed) {
  TimingFault fault;
  fault.stamp_error = 0.05;
  fault.reversed = true;
  checkFaultedBag(findScenario("LDS-01/high/turns"), fault, "late_reversed");
}

TEST(SimBag, StampedEarly) {
  TimingFault fault;
  fault.stamp_error = -0.3;  // before the first scan's tf margin: odometry starts earlier
  checkFaultedBag(findScenario("ILD26TRI/high/turns"), fault, "early");
}

TEST(SimBag, StampedAtEndWithLongIncrement) {
  const Scenario scenario = findScenario("ILD26TRI/normal/turns");
  TimingFault fault = TimingFault::stampedAtEnd(scenario.lidar);
  fault.time_increment_factor = 2.0;  // claims a sweep twice as long: odometry ends later
  checkFaultedBag(scenario, fault, "end_double");
}

TEST(SimBag, NoPeriodAtAll) {
  TimingFault fault;
  fault.time_increment_factor = 0.0;
  fault.zero_scan_time = true;
  checkFaultedBag(findScenario("UTM-30LX-270/normal/turns"), fault, "no_period");
}

TEST(SimBag, InvalidOptionsAreRefused) {
  SimBagOptions options;
  options.timing_fault.time_increment_factor = -1.0;
  const std::string bag_path = ::testing::TempDir() + "/sim_invalid.bag";
  EXPECT_THROW(
      writeSimulationBag(findScenario("LDS-01/normal/turns"), options, bag_path, bag_path + ".truth"),
      std::invalid_argument);
  options = SimBagOptions();
  options.tf_margin = -0.1;
  EXPECT_THROW(
      writeSimulationBag(findScenario("LDS-01/normal/turns"), options, bag_path, bag_path + ".truth"),
      std::invalid_argument);
}

}  // namespace
}  // namespace lidar_deskew::sim
