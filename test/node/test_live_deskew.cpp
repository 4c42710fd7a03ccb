// The live deskew against a real roscore: one test source, run by rostest against the plain node
// (live_node.test), the nodelet (live_nodelet.test) and the node with on_tf_failure: pass_through
// (live_pass_through.test). The driver plays the simulator's 6 m/s, 5 rad/s arc through /tf at 50 Hz
// and publishes its UTM-30LX scans (1440 beams, 40 Hz); the laser sits 0.25 m ahead of the base.
#include <gtest/gtest.h>

#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

bool expectPassThrough() {
  return testFlag("expect_pass_through");
}

constexpr double kScanPeriod = 1.0 / 40.0;

// Runs first: nobody listens yet, so the deskew must not subscribe to its input.
TEST(LiveDeskew, SubscribesToItsInputOnlyWhileSomeoneListens) {
  LiveRig rig;
  ros::WallDuration(1.0).sleep();
  ros::spinOnce();
  EXPECT_EQ(rig.scan_publisher.getNumSubscribers(), 0u);
  rig.subscribeOutputs();
  EXPECT_TRUE(rig.waitFor([&] { return rig.scan_publisher.getNumSubscribers() == 1; }, 5.0));
  rig.unsubscribeOutputs();
  EXPECT_TRUE(rig.waitFor([&] { return rig.scan_publisher.getNumSubscribers() == 0; }, 5.0));
}

TEST(LiveDeskew, CorrectedCloudAndScanLieOnTheTrueWalls) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  std::vector<double> cloud_errors, scan_errors, raw_errors;
  for (int k = 0; k < 10; ++k) {
    const double start = 0.1 + k * kScanPeriod;
    rig.publishTfUntil(start + kScanPeriod + 0.02);  // tf covers the sweep: processed at once
    const sim::SimulatedScan input = rig.publishScan(start);
    sensor_msgs::LaserScan::ConstPtr scan;
    sensor_msgs::PointCloud2::ConstPtr cloud;
    ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 5.0, scan, cloud)) << "scan " << k;
    // The corrected scan keeps the input's grid and beam count (gmapping needs a fixed count).
    EXPECT_EQ(scan->ranges.size(), input.scan.ranges.size());
    EXPECT_EQ(scan->angle_min, input.scan.angle_min);
    EXPECT_EQ(scan->angle_increment, input.scan.angle_increment);
    EXPECT_EQ(scan->time_increment, 0.0f);
    EXPECT_EQ(scan->header.frame_id, "laser");
    EXPECT_EQ(cloud->header.frame_id, "laser");
    EXPECT_EQ(cloud->width, 1440u);
    for (double d : cloudDistances(rig, *cloud))
      cloud_errors.push_back(d);
    for (double d : scanDistances(rig, *scan))
      scan_errors.push_back(d);
    // The raw scan, drawn at its stamp, for comparison.
    for (double d : rawDistances(rig, input, start))
      raw_errors.push_back(d);
  }
  std::printf("distance to the true walls, RMS: raw %.2f mm, cloud %.3f mm, scan %.3f mm\n",
              1e3 * rms(raw_errors), 1e3 * rms(cloud_errors), 1e3 * rms(scan_errors));
  EXPECT_GT(rms(raw_errors), 0.1);     // decimetres
  EXPECT_LT(rms(cloud_errors), 2e-3);  // noise off: < 2 mm
  EXPECT_LT(rms(scan_errors), 3e-3);   // < 3 mm
  EXPECT_GT(scan_errors.size(), 10u * 1400u);
}

// A scan whose sweep tf never covers: dropped and counted, or passed through uncorrected.
TEST(LiveDeskew, TfGapDropsOrPassesThrough) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 1.0;
  rig.publishTfUntil(start - 0.01);  // tf stops before the sweep (too early to extrapolate from)
  const sim::SimulatedScan input = rig.publishScan(start);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  const bool arrived = rig.waitForOutputs(rig.stampOf(start), 1.5, scan, cloud);  // tf_timeout is 0.2 s
  if (expectPassThrough()) {
    ASSERT_TRUE(arrived);
    ASSERT_EQ(scan->ranges.size(), input.scan.ranges.size());
    for (std::size_t i = 0; i < scan->ranges.size(); ++i)
      EXPECT_EQ(scan->ranges[i], input.scan.ranges[i]);
    EXPECT_EQ(cloud->width, 1440u);
    EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("passed through") >= 1; }, 5.0));
  } else {
    EXPECT_FALSE(arrived);
    EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("dropped: tf") >= 1; }, 5.0))
        << rig.diagnostic("dropped: tf");
  }
  // tf resumes: the next scan is served.
  const double next = start + 0.5;
  rig.publishTfUntil(next + kScanPeriod + 0.02);
  rig.publishScan(next);
  EXPECT_TRUE(rig.waitForOutputs(rig.stampOf(next), 5.0, scan, cloud));
}

TEST(LiveDeskew, MalformedScanIsDroppedAndTheNextServed) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 2.0;
  rig.publishTfUntil(start + 3 * kScanPeriod + 0.02);
  rig.publishScan(start, [](sensor_msgs::LaserScan& message) { message.intensities.assign(7, 1.0f); });
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(start), 1.0, scan, cloud));
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("dropped: invalid") >= 1; }, 5.0));
  rig.publishScan(start + kScanPeriod,
                  [](sensor_msgs::LaserScan& message) { message.angle_increment = NAN; });
  const double next = start + 2 * kScanPeriod;
  rig.publishScan(next);
  EXPECT_TRUE(rig.waitForOutputs(rig.stampOf(next), 5.0, scan, cloud));
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("dropped: invalid") >= 2; }, 5.0));
}

// tf ends 5 ms before the sweep's last beam. Without max_extrapolation the scan waits until tf covers
// it. With it (0.05 s here, tf_timeout 0.5 s), extrapolation backs the wait up, it does not replace it:
// tf that comes within tf_timeout is waited for and the scan corrected exactly; only when tf_timeout
// passes without it is the scan extrapolated with the newest velocity instead of dropped.
TEST(LiveDeskew, ExtrapolatesOnlyWhenAllowedAndOnlyOnceTheWaitIsOver) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  double start = 3.0;  // sweep [3.0, 3.025): tf up to 3.0 + 0.02 - ends 5 ms short
  rig.publishTfUntil(start + 0.02);
  rig.publishScan(start);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(start), 0.1, scan, cloud));  // tf_timeout is 0.2 or 0.5 s
  if (testFlag("expect_extrapolation")) {
    // tf never comes: extrapolated once the wait is over.
    ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 1.5, scan, cloud));
    // 5 ms of constant-velocity extrapolation on a 6 m/s, 5 rad/s arc: millimetres at most.
    EXPECT_LT(rms(cloudDistances(rig, *cloud)), 3e-3);
    EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("extrapolated") >= 1; }, 5.0));
    // tf 80 ms late, well within tf_timeout: waited for, corrected exactly, not extrapolated.
    start = 3.5;
    rig.publishTfUntil(start + 0.02);
    rig.publishScan(start);
    rig.spinFor(0.08);
    rig.publishTfUntil(start + 0.06);
    ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 1.5, scan, cloud));
    EXPECT_LT(rms(cloudDistances(rig, *cloud)), 1e-3);
    rig.spinFor(1.2);  // a diagnostics period
    EXPECT_EQ(rig.diagnosticNumber("extrapolated"), 1.0);
  } else {
    rig.publishTfUntil(start + 0.06);
    EXPECT_TRUE(rig.waitForOutputs(rig.stampOf(start), 5.0, scan, cloud));
  }
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_live_deskew");
  return RUN_ALL_TESTS();
}
