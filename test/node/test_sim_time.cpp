// The live node on a simulated clock (use_sim_time, as beside `rosbag play --clock`): waiting for tf
// counts clock time, so a paused clock drops nothing; /diagnostics keeps coming when the clock stands
// still or goes back (a bag played again); a /clock reset alone is a time jump. This test owns /clock.
#include <gtest/gtest.h>
#include <rosgraph_msgs/Clock.h>

#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

class SimClock {
 public:
  SimClock() : publisher_(ros::NodeHandle().advertise<rosgraph_msgs::Clock>("/clock", 10)) {}
  void set(double seconds) {
    rosgraph_msgs::Clock clock;
    clock.clock.fromSec(seconds);
    publisher_.publish(clock);
  }
  /// Once the node listens: sets the clock and waits (wall time) until this process sees it.
  bool startAt(double seconds) {
    LiveRig waiter;
    if (!waiter.waitFor([&] { return publisher_.getNumSubscribers() > 0; }, 10.0))
      return false;
    set(seconds);
    return waiter.waitFor([&] { return ros::Time::now().toSec() == seconds; }, 5.0);
  }
  ros::Publisher publisher_;
};

constexpr double kScanPeriod = 1.0 / 40.0;

TEST(SimTime, PausedClockDropsNothingAndDiagnosticsGoOnWhenTimeGoesBack) {
  SimClock clock;
  ASSERT_TRUE(clock.startAt(1000.0));

  LiveRig rig;  // t = 0 is sim time 1000 s
  ASSERT_TRUE(rig.connect());
  rig.publishTfUntil(0.1);
  // The clock stands still (a paused bag) while the scan's tf is late: 1 s of wall time, 5 x tf_timeout.
  rig.publishScan(0.1);
  rig.spinFor(1.0);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("received") >= 1.0; }, 3.0));
  EXPECT_EQ(rig.diagnosticNumber("dropped: tf"), 0.0);
  EXPECT_EQ(rig.diagnosticNumber("waiting scans"), 1.0);
  // Stepping on: tf comes, the scan is corrected.
  clock.set(1000.2);
  rig.publishTfUntil(0.1 + kScanPeriod + 0.02);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(0.1), 5.0, scan, cloud));
  EXPECT_LT(rms(cloudDistances(rig, *cloud)), 2e-3);

  // The clock goes back 500 s (the bag starts again): diagnostics keep coming, about one a second.
  clock.set(500.0);
  rig.spinFor(0.5);
  const std::size_t before = rig.diagnosticsReceived();
  rig.spinFor(3.0);
  EXPECT_GE(rig.diagnosticsReceived(), before + 2);
}

// A /clock reset alone (a simulator restarted; no tf of the new time line yet) while a scan waits: it
// is a time jump. Before, the scan waited until the clock came back to where it had been.
TEST(SimTime, ClockResetAloneIsATimeJump) {
  SimClock clock;
  ASSERT_TRUE(clock.startAt(2000.0));

  LiveRig rig;  // t = 0 is sim time 2000 s
  ASSERT_TRUE(rig.connect());
  rig.publishTfUntil(0.1);
  rig.publishScan(0.1);  // its tf never comes
  ASSERT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("waiting scans") == 1.0; }, 5.0));
  const double jumps = rig.diagnosticNumber("time jumps");
  const double dropped = rig.diagnosticNumber("dropped: tf");
  clock.set(100.0);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("waiting scans") == 0.0; }, 5.0));
  EXPECT_EQ(rig.diagnosticNumber("time jumps"), jumps + 1);
  EXPECT_EQ(rig.diagnosticNumber("dropped: tf"), dropped + 1);
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_sim_time");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
