// Simulated LaserScan bags with timing faults read back with the rosbag C++ API: every /scan carries
// the faulted stamp, time_increment and scan_time over the truly measured ranges (those of
// simulateScan with the same fault), record times never precede stamps, odometry covers the beam
// times both as true and as claimed, and the truth file holds the fault and the true periods.
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lidar_deskew/sim/sim_bag.h"
#include "support/temporary.h"

namespace lidar_deskew::sim {
namespace {

struct Recorded {
  std::vector<sensor_msgs::LaserScan> scans;
  std::vector<core::TimeNs> scan_record_times;
  std::vector<core::TimeNs> tf_times;  // [ns] stamps of odom -> base_link
  std::vector<Pose2> tf_poses;         // odom -> base_link, its yaw from the quaternion
  std::vector<core::TimeNs> tf_record_times;
  std::vector<nav_msgs::Odometry> odometry;
  std::vector<core::TimeNs> record_times;  // of every message, in file order
  std::size_t latched_tf_static = 0;       // /tf_static messages whose connection latches
};

/// Whether a message's connection was latched when recorded (as `rosbag record` notes it).
bool latched(const rosbag::MessageInstance& message) {
  const auto header = message.getConnectionHeader();
  if (!header)
    return false;
  const auto latching = header->find("latching");
  return latching != header->end() && latching->second == "1";
}

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
      for (const auto& transform : transforms->transforms) {
        recorded.tf_times.push_back(static_cast<core::TimeNs>(transform.header.stamp.toNSec()));
        recorded.tf_record_times.push_back(static_cast<core::TimeNs>(message.getTime().toNSec()));
        const auto& q = transform.transform.rotation;
        recorded.tf_poses.push_back({transform.transform.translation.x, transform.transform.translation.y,
                                     2.0 * std::atan2(q.z, q.w)});
      }
    } else if (message.getTopic() == "/odom") {
      recorded.odometry.push_back(*message.instantiate<nav_msgs::Odometry>());
    } else if (message.getTopic() == "/tf_static") {
      recorded.latched_tf_static += latched(message) ? 1 : 0;
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
  const std::string bag_path = test::temporary("sim", label + ".bag");
  const std::string truth_path = test::temporary("sim", label + ".truth");
  writeSimulationBag(scenario, options, bag_path, truth_path);
  const Recorded recorded = readBag(bag_path);
  // /tf_static once, latched as rosbag record notes it (rosbag play then latches it).
  EXPECT_EQ(recorded.latched_tf_static, 1u);

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

// Odometry noise (10 % per 20 ms step) on the LDS-01 arc with range noise and tf at 40 Hz (every other
// sample between the odometry's grid points): the scans are bit-equal to those of perfect odometry;
// with perfect odometry /tf is the truth (x, y exactly, yaw through the quaternion); with noise /tf and
// /odom carry NoisyOdometry's poses (same start, steps and seed) and the true twist times the step's
// factors, and drift away from the truth; the truth file keeps the true motion and records the noise.
TEST(SimBag, OdometryNoise) {
  const Scenario scenario = findScenario("LDS-01/normal/arc");
  const std::string stem = test::temporary("sim", "odometry");
  SimBagOptions options;
  options.noise = true;
  options.seed = 5;
  options.tf_rate = 40.0;
  writeSimulationBag(scenario, options, stem + "_perfect.bag", stem + "_perfect.truth");
  options.odom_noise = 0.1;
  options.odom_noise_seed = 9;
  writeSimulationBag(scenario, options, stem + "_noisy.bag", stem + "_noisy.truth");
  const Recorded perfect = readBag(stem + "_perfect.bag"), noisy = readBag(stem + "_noisy.bag");

  ASSERT_EQ(perfect.scans.size(), 8u);
  ASSERT_EQ(noisy.scans.size(), perfect.scans.size());
  for (std::size_t k = 0; k < perfect.scans.size(); ++k)
    EXPECT_EQ(noisy.scans[k].ranges, perfect.scans[k].ranges) << k;

  const PiecewiseTrajectory trajectory = scenario.trajectory();
  ASSERT_EQ(perfect.tf_times, noisy.tf_times);
  ASSERT_EQ(noisy.odometry.size(), noisy.tf_times.size());
  const auto seconds = [&](core::TimeNs time) { return core::nsToSeconds(time - options.epoch); };
  const double first = -0.1;  // tf_margin before the first scan
  const NoisyOdometry model(trajectory, first, seconds(noisy.tf_times.back()), 0.1, 9);
  double drift = 0.0;
  for (std::size_t k = 0; k < noisy.tf_times.size(); ++k) {
    // The writer's sample time (the stamp is its ns rounding): the first sample, then every 1 / 40 s.
    const double t = -4.0 / 40.0 + static_cast<double>(k) / 40.0;
    EXPECT_NEAR(seconds(noisy.tf_times[k]), t, 1e-9) << k;
    const Pose2 truth = trajectory.pose(t);
    EXPECT_EQ(perfect.tf_poses[k].x, truth.x) << k;
    EXPECT_EQ(perfect.tf_poses[k].y, truth.y) << k;
    EXPECT_NEAR(std::remainder(perfect.tf_poses[k].yaw - truth.yaw, 2.0 * M_PI), 0.0, 1e-12) << k;
    EXPECT_EQ(perfect.odometry[k].twist.twist.linear.x, 1.5);
    EXPECT_EQ(perfect.odometry[k].twist.twist.angular.z, 2.0);

    const Pose2 expected = model.pose(t);
    EXPECT_NEAR(noisy.tf_poses[k].x, expected.x, 1e-9) << k;
    EXPECT_NEAR(noisy.tf_poses[k].y, expected.y, 1e-9) << k;
    EXPECT_NEAR(std::remainder(noisy.tf_poses[k].yaw - expected.yaw, 2.0 * M_PI), 0.0, 1e-9) << k;
    EXPECT_EQ(noisy.odometry[k].pose.pose.position.x, noisy.tf_poses[k].x);
    const NoisyOdometry::Factors factors = model.factors(t);
    EXPECT_NEAR(noisy.odometry[k].twist.twist.linear.x, 1.5 * factors.x, 1e-12) << k;
    EXPECT_NEAR(noisy.odometry[k].twist.twist.angular.z, 2.0 * factors.yaw, 1e-12) << k;
    drift = std::max(drift, std::hypot(noisy.tf_poses[k].x - truth.x, noisy.tf_poses[k].y - truth.y));
  }
  std::printf("odometry 10 %% per step: largest drift from the truth %.1f mm over %.1f s\n", 1e3 * drift,
              seconds(noisy.tf_times.back()) - first);
  EXPECT_GT(drift, 0.001);

  const Truth truth = readTruth(stem + "_noisy.truth");
  EXPECT_EQ(truth.odom_noise, 0.1);
  EXPECT_EQ(truth.odom_noise_seed, 9u);
  EXPECT_EQ(truth.start.y, scenario.start.y);
  ASSERT_EQ(truth.pieces.size(), 1u);
  EXPECT_EQ(truth.pieces[0].yaw_rate, 2.0);
  EXPECT_EQ(readTruth(stem + "_perfect.truth").odom_noise, 0.0);
  for (const char* file : {"_perfect.bag", "_perfect.truth", "_noisy.bag", "_noisy.truth"})
    std::remove((stem + file).c_str());
}

TEST(SimBag, InvalidOptionsAreRefused) {
  SimBagOptions options;
  options.timing_fault.time_increment_factor = -1.0;
  const std::string bag_path = test::temporary("sim", "invalid.bag");
  EXPECT_THROW(
      writeSimulationBag(findScenario("LDS-01/normal/turns"), options, bag_path, bag_path + ".truth"),
      std::invalid_argument);
  options = SimBagOptions();
  options.odom_noise = -0.1;
  EXPECT_THROW(
      writeSimulationBag(findScenario("LDS-01/normal/turns"), options, bag_path, bag_path + ".truth"),
      std::invalid_argument);
  options = SimBagOptions();
  options.tf_margin = -0.1;
  EXPECT_THROW(
      writeSimulationBag(findScenario("LDS-01/normal/turns"), options, bag_path, bag_path + ".truth"),
      std::invalid_argument);
}

// Odometry as robots produce it (OdometryTiming), on 1 s of the LDS-01 arc (5 Hz scans; 1.5 m/s, 2 rad/s)
// with perfect odometry, so that every pose is checked against the true motion.
struct OdometryBag {
  Scenario scenario;
  SimBagOptions options;
  Recorded recorded;
  Truth truth;
  double seconds(core::TimeNs time) const { return core::nsToSeconds(time - options.epoch); }
};

OdometryBag writeOdometryBag(const OdometryTiming& timing, const std::string& label, double duration = 1.0,
                             unsigned seed = 4) {
  OdometryBag result;
  result.scenario = findScenario("LDS-01/normal/arc");
  result.scenario.duration = duration;
  result.options.odom_timing = timing;
  result.options.odom_noise_seed = seed;
  const std::string stem = test::temporary("sim_odom", label);
  writeSimulationBag(result.scenario, result.options, stem + ".bag", stem + ".truth");
  result.recorded = readBag(stem + ".bag");
  result.truth = readTruth(stem + ".truth");
  std::remove((stem + ".bag").c_str());
  std::remove((stem + ".truth").c_str());
  return result;
}

// Stamps jittered by up to 5 ms at 50 Hz: sample k is at its grid time (one more sample at each end,
// 20 ms before -0.1 s), its stamp within 5 ms of it (and some near 5 ms), its pose the truth at the
// grid time, not at the stamp.
TEST(SimBagOdometry, StampJitter) {
  OdometryTiming timing;
  timing.jitter = 0.005;
  const OdometryBag bag = writeOdometryBag(timing, "jitter");
  const Recorded& recorded = bag.recorded;
  ASSERT_EQ(recorded.tf_times.size(), 73u);  // -0.12 .. 1.32 s: 5 scans of 0.2 s, 0.1 s margins, +-1
  // Stamps 20 ms apart jittered by 5 ms stay in order.
  ASSERT_TRUE(std::is_sorted(recorded.tf_times.begin(), recorded.tf_times.end()));
  const PiecewiseTrajectory trajectory = bag.scenario.trajectory();
  double largest_error = 0.0, largest_offset = 0.0;
  for (std::size_t k = 0; k < recorded.tf_times.size(); ++k) {
    const double t = -0.12 + static_cast<double>(k) / 50.0;
    const double stamp = bag.seconds(recorded.tf_times[k]);
    EXPECT_LE(std::abs(stamp - t), 0.005 + 1e-9) << k;
    largest_error = std::max(largest_error, std::abs(stamp - t));
    const Pose2 truth = trajectory.pose(t);
    EXPECT_NEAR(recorded.tf_poses[k].x, truth.x, 1e-12) << k;
    EXPECT_NEAR(recorded.tf_poses[k].y, truth.y, 1e-12) << k;
    const Pose2 at_stamp = trajectory.pose(stamp);
    largest_offset = std::max(largest_offset, std::hypot(at_stamp.x - truth.x, at_stamp.y - truth.y));
    EXPECT_EQ(recorded.tf_record_times[k], recorded.tf_times[k]);  // recorded at once
  }
  std::printf("jitter 5 ms: largest stamp error %.2f ms, pose at the stamp off by up to %.1f mm\n",
              1e3 * largest_error, 1e3 * largest_offset);
  EXPECT_GT(largest_error, 0.004);
  EXPECT_GT(largest_offset, 0.006);  // 1.5 m/s x 4 ms
  EXPECT_EQ(bag.truth.odom_timing.jitter, 0.005);
}

// 5 to 11 Hz over 4 s: every interval in [1/11, 1/5] s, both ends of the range reached, the poses the
// truth at the stamps, the stamps covering all scans.
TEST(SimBagOdometry, IrregularRate) {
  OdometryTiming timing;
  timing.rate_min = 5.0;
  timing.rate_max = 11.0;
  const OdometryBag bag = writeOdometryBag(timing, "rate", 4.0);
  const Recorded& recorded = bag.recorded;
  ASSERT_GT(recorded.tf_times.size(), 25u);
  ASSERT_EQ(recorded.odometry.size(), recorded.tf_times.size());
  const PiecewiseTrajectory trajectory = bag.scenario.trajectory();
  double shortest = 1.0, longest = 0.0;
  for (std::size_t k = 0; k < recorded.tf_times.size(); ++k) {
    const double stamp = bag.seconds(recorded.tf_times[k]);
    const Pose2 truth = trajectory.pose(stamp);
    EXPECT_NEAR(recorded.tf_poses[k].x, truth.x, 1e-6) << k;  // the stamp is the time rounded to 1 ns
    EXPECT_NEAR(recorded.tf_poses[k].y, truth.y, 1e-6) << k;
    if (k == 0)
      continue;
    const double interval = stamp - bag.seconds(recorded.tf_times[k - 1]);
    EXPECT_GE(interval, 1.0 / 11.0 - 2e-9) << k;
    EXPECT_LE(interval, 1.0 / 5.0 + 2e-9) << k;
    shortest = std::min(shortest, interval);
    longest = std::max(longest, interval);
  }
  std::printf("5-11 Hz: %zu samples, intervals %.1f to %.1f ms\n", recorded.tf_times.size(), 1e3 * shortest,
              1e3 * longest);
  EXPECT_LT(shortest, 1.0 / 11.0 + 0.015);
  EXPECT_GT(longest, 1.0 / 5.0 - 0.015);
  EXPECT_LE(recorded.tf_times.front(),
            static_cast<core::TimeNs>(recorded.scans.front().header.stamp.toNSec()));
  const double last_end = bag.seconds(recorded.scans.back().header.stamp.toNSec()) + 0.2;
  EXPECT_GE(bag.seconds(recorded.tf_times.back()), last_end);
  EXPECT_EQ(bag.truth.odom_timing.rate_min, 5.0);
  EXPECT_EQ(bag.truth.odom_timing.rate_max, 11.0);
}

// Encoders of 1 mm ticks on a 0.16 m wheel base: between samples, the heading step is an integer
// number of 1 mm / 0.16 m and the arc length half an integer number of ticks (the two of the same
// parity: nl + nr and nr - nl); the heading never more than two ticks' worth (2 mm / 0.16 m) off the
// truth; /odom's twist the interval's ticks over its duration.
TEST(SimBagOdometry, EncoderTicks) {
  OdometryTiming timing;
  timing.tick = 0.001;
  timing.wheel_base = 0.16;
  const OdometryBag bag = writeOdometryBag(timing, "ticks");
  const Recorded& recorded = bag.recorded;
  ASSERT_EQ(recorded.tf_times.size(), 71u);  // -0.1 .. 1.3 s
  const PiecewiseTrajectory trajectory = bag.scenario.trajectory();
  const auto nearInteger = [](double x) { return std::abs(x - std::round(x)); };
  double largest_residual = 0.0, largest_heading_error = 0.0;
  for (std::size_t k = 1; k < recorded.tf_times.size(); ++k) {
    const Pose2 step = recorded.tf_poses[k - 1].between(recorded.tf_poses[k]);
    const double half = 0.5 * step.yaw;
    const double arc =
        std::copysign(std::hypot(step.x, step.y), step.x) * (half == 0.0 ? 1.0 : half / std::sin(half));
    const double difference = step.yaw * 0.16 / 0.001;  // nr - nl
    const double sum = 2.0 * arc / 0.001;               // nr + nl
    largest_residual = std::max({largest_residual, nearInteger(difference), nearInteger(sum)});
    EXPECT_EQ(std::lround(sum + difference) % 2, 0) << k;
    const double t = bag.seconds(recorded.tf_times[k]);
    const double dt = t - bag.seconds(recorded.tf_times[k - 1]);
    EXPECT_NEAR(recorded.odometry[k].twist.twist.linear.x, arc / dt, 1e-6) << k;
    EXPECT_NEAR(recorded.odometry[k].twist.twist.angular.z, step.yaw / dt, 1e-6) << k;
    largest_heading_error =
        std::max(largest_heading_error,
                 std::abs(std::remainder(recorded.tf_poses[k].yaw - trajectory.pose(t).yaw, 2 * M_PI)));
  }
  std::printf(
      "1 mm ticks, 0.16 m base: increments within %.1e of whole ticks, heading off by up to %.2f deg\n",
      largest_residual, largest_heading_error * 180.0 / M_PI);
  EXPECT_LT(largest_residual, 1e-6);
  EXPECT_LE(largest_heading_error, 2.0 * 0.001 / 0.16 + 1e-9);
  EXPECT_GT(largest_heading_error, 0.001);
  EXPECT_EQ(bag.truth.odom_timing.tick, 0.001);
  EXPECT_EQ(bag.truth.odom_timing.wheel_base, 0.16);
}

// Recorded 30 ms late in bursts of 3: /tf sample k recorded at the stamp of the last of its burst + 30
// ms, its stamp still its grid time; the scans still recorded at their sweeps' ends.
TEST(SimBagOdometry, LateAndBursty) {
  OdometryTiming timing;
  timing.late = 0.03;
  timing.burst = 3;
  const OdometryBag bag = writeOdometryBag(timing, "delivery");
  const Recorded& recorded = bag.recorded;
  const std::size_t n = recorded.tf_times.size();
  ASSERT_EQ(n, 71u);
  for (std::size_t k = 0; k < n; ++k) {
    EXPECT_NEAR(bag.seconds(recorded.tf_times[k]), -0.1 + static_cast<double>(k) / 50.0, 1e-9) << k;
    const std::size_t last = std::min(n - 1, 3 * (k / 3) + 2);
    EXPECT_NEAR(static_cast<double>(recorded.tf_record_times[k] - recorded.tf_times[last]), 30e6, 2.0) << k;
  }
  for (std::size_t k = 0; k < recorded.scans.size(); ++k)
    EXPECT_NEAR(bag.seconds(recorded.scan_record_times[k]), 0.2 * static_cast<double>(k + 1), 1e-9) << k;
  EXPECT_EQ(bag.truth.odom_timing.late, 0.03);
  EXPECT_EQ(bag.truth.odom_timing.burst, 3);
}

// All of it together with noise: the same seed writes the same bag; another seed another one.
TEST(SimBagOdometry, SameSeedSameBag) {
  OdometryTiming timing;
  timing.jitter = 0.004;
  timing.rate_min = 6.0;
  timing.rate_max = 11.0;
  timing.tick = 0.001;
  timing.wheel_base = 0.235;
  timing.late = 0.02;
  timing.burst = 2;
  const OdometryBag first = writeOdometryBag(timing, "seed_a", 1.0, 7);
  const OdometryBag again = writeOdometryBag(timing, "seed_b", 1.0, 7);
  const OdometryBag other = writeOdometryBag(timing, "seed_c", 1.0, 8);
  EXPECT_EQ(first.recorded.tf_times, again.recorded.tf_times);
  EXPECT_EQ(first.recorded.record_times, again.recorded.record_times);
  ASSERT_EQ(first.recorded.tf_poses.size(), again.recorded.tf_poses.size());
  for (std::size_t k = 0; k < first.recorded.tf_poses.size(); ++k) {
    EXPECT_EQ(first.recorded.tf_poses[k].x, again.recorded.tf_poses[k].x);
    EXPECT_EQ(first.recorded.tf_poses[k].yaw, again.recorded.tf_poses[k].yaw);
  }
  EXPECT_NE(first.recorded.tf_times, other.recorded.tf_times);
  EXPECT_EQ(first.truth.odom_noise_seed, 7u);
}

TEST(SimBagOdometry, InvalidTimingIsRefused) {
  const std::string bag_path = test::temporary("sim", "invalid_timing.bag");
  const auto refused = [&](const OdometryTiming& timing) {
    SimBagOptions options;
    options.odom_timing = timing;
    EXPECT_THROW(
        writeSimulationBag(findScenario("LDS-01/normal/arc"), options, bag_path, bag_path + ".truth"),
        std::invalid_argument);
  };
  OdometryTiming timing;
  timing.rate_min = 11.0;
  timing.rate_max = 5.0;
  refused(timing);
  timing = OdometryTiming();
  timing.tick = 0.001;
  refused(timing);
  timing = OdometryTiming();
  timing.burst = 0;
  refused(timing);
  timing = OdometryTiming();
  timing.jitter = -0.001;
  refused(timing);
}

}  // namespace
}  // namespace lidar_deskew::sim
