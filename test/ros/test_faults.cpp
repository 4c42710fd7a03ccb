// Fault injection against the live node with a real roscore (DESIGN §5). Each test states the expected
// behaviour and checks it, including the diagnostics counters.
#include <gtest/gtest.h>

#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

constexpr double kScanPeriod = 1.0 / 40.0;

/// Plays `count` scans from `start`, each with tf covering it first; returns how many outputs came.
int playCovered(LiveRig& rig, double start, int count, double period = kScanPeriod) {
  int received = 0;
  for (int k = 0; k < count; ++k) {
    const double t = start + k * period;
    rig.publishTfUntil(t + kScanPeriod + 0.02);
    rig.publishScan(t);
    sensor_msgs::LaserScan::ConstPtr scan;
    sensor_msgs::PointCloud2::ConstPtr cloud;
    received += rig.waitForOutputs(rig.stampOf(t), 5.0, scan, cloud);
  }
  return received;
}

// tf arrives late (after the scan, within tf_timeout): the scan waits and is then corrected.
TEST(Faults, LateTfIsWaitedFor) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 0.5;
  rig.publishTfUntil(start);
  rig.publishScan(start);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(start), 0.05, scan, cloud));  // waiting, not dropped
  rig.publishTfUntil(start + kScanPeriod + 0.02);                           // tf arrives 50 ms late
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 5.0, scan, cloud));
  EXPECT_LT(rms(cloudDistances(rig, *cloud)), 2e-3);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("tf wait max [ms]") >= 40.0; }, 5.0))
      << rig.diagnostic("tf wait max [ms]");
}

// tf jumps back in time (a bag loop): one warning, the tf cache and the queue are cleared, the jump is
// counted, and scans of the new time line are corrected again.
TEST(Faults, TfJumpingBackClearsAndRecovers) {
  LiveRig later;
  ASSERT_TRUE(later.connect());
  ASSERT_EQ(playCovered(later, 20.0, 3), 3);  // stamps 20 s ahead of now
  LiveRig rig;                                // a new time line, starting now: 20 s back
  ASSERT_TRUE(rig.connect());
  EXPECT_EQ(playCovered(rig, 0.5, 3), 3);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("time jumps") >= 1; }, 5.0));
}

// The same scan twice (a duplicate stamp): each is corrected and published; nothing is dropped.
TEST(Faults, DuplicateStampIsCorrectedTwice) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 40.0;
  rig.publishTfUntil(start + kScanPeriod + 0.02);
  rig.publishScan(start);
  rig.publishScan(start);
  EXPECT_TRUE(rig.waitFor([&] { return rig.outputCount(rig.stampOf(start), rig.stampOf(start)) == 2; }, 5.0));
  EXPECT_TRUE(rig.waitFor([&] { return !rig.diagnostic("dropped: invalid").empty(); }, 5.0));
  EXPECT_EQ(rig.diagnosticNumber("dropped: invalid"), 0.0);
  EXPECT_EQ(rig.diagnosticNumber("dropped: queue"), 0.0);
}

// Scans at 4x the sensor's rate (160 Hz of 1440 beams): all corrected, none dropped.
TEST(Faults, FourTimesTheRateIsServed) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 60.0;
  const int count = 80;
  rig.publishTfUntil(start + count * kScanPeriod / 4 + kScanPeriod + 0.02);
  const ros::WallTime begin = ros::WallTime::now();
  for (int k = 0; k < count; ++k) {
    rig.publishScan(start + k * kScanPeriod / 4);
    ros::WallDuration(kScanPeriod / 4).sleep();
    ros::spinOnce();
  }
  const double elapsed = (ros::WallTime::now() - begin).toSec();
  const ros::Time first = rig.stampOf(start), last = rig.stampOf(start + (count - 1) * kScanPeriod / 4);
  EXPECT_TRUE(
      rig.waitFor([&] { return rig.outputCount(first, last) == static_cast<std::size_t>(count); }, 10.0))
      << rig.outputCount(first, last) << " of " << count;
  EXPECT_LT(elapsed, count * kScanPeriod / 4 * 2.0);  // the driver really published at about 160 Hz
  EXPECT_TRUE(rig.waitFor(
      [&] {
        return rig.diagnosticNumber("dropped: queue") == 0.0 && rig.diagnosticNumber("dropped: tf") == 0.0;
      },
      5.0));
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_faults");
  return RUN_ALL_TESTS();
}
