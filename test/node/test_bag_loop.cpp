// A real bag played on the ROS clock with `rosbag play --loop` (bag_loop.test): the node corrects scans
// and /diagnostics keeps coming in the first pass and after the clock wraps back to the bag's start,
// and the wrap is counted as a time jump. Before diagnostics ran on the wall clock, they fell silent
// for good after the wrap.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/LaserScan.h>

#include <string>

namespace {

struct Pass {
  int scans = 0;        // corrected scans out
  int diagnostics = 0;  // statuses of the deskew on /diagnostics
  double time_jumps = -1.0;
};

TEST(BagLoop, DiagnosticsAndScansInBothPasses) {
  ros::NodeHandle nh;
  Pass passes[2];
  int pass = 0;
  double last_clock = -1.0;
  // /clock going back by more than a second: the bag started again.
  ros::Subscriber clock =
      nh.subscribe<rosgraph_msgs::Clock>("/clock", 100, [&](const rosgraph_msgs::Clock::ConstPtr& c) {
        const double now = c->clock.toSec();
        if (last_clock > 0.0 && now + 1.0 < last_clock && pass == 0)
          pass = 1;
        last_clock = now;
      });
  ros::Subscriber scans = nh.subscribe<sensor_msgs::LaserScan>(
      "/stable_scan_deskewed", 100, [&](const sensor_msgs::LaserScan::ConstPtr&) { ++passes[pass].scans; });
  ros::Subscriber diagnostics = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
        for (const auto& status : array->status) {
          if (status.name.find("deskew") == std::string::npos)
            continue;
          ++passes[pass].diagnostics;
          for (const auto& value : status.values) {
            if (value.key == "time jumps")
              passes[pass].time_jumps = std::stod(value.value);
          }
        }
      });
  // Until the second pass has run 3 s of wall time (the bag is 12 s long, played 3 x as fast).
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(40.0);
  ros::WallTime second_began;
  while (ros::WallTime::now() < deadline) {
    ros::spinOnce();
    ros::WallDuration(0.005).sleep();
    if (pass == 1 && second_began.isZero())
      second_began = ros::WallTime::now();
    if (!second_began.isZero() && (ros::WallTime::now() - second_began).toSec() > 3.0)
      break;
  }
  ASSERT_EQ(pass, 1) << "the bag did not start again within 40 s";
  for (int p = 0; p < 2; ++p) {
    std::printf("pass %d: %d corrected scans, %d diagnostics, time jumps %.0f\n", p + 1, passes[p].scans,
                passes[p].diagnostics, passes[p].time_jumps);
    EXPECT_GE(passes[p].scans, 10) << "pass " << p + 1;
    EXPECT_GE(passes[p].diagnostics, 2) << "pass " << p + 1;
  }
  EXPECT_EQ(passes[0].time_jumps, 0.0);
  EXPECT_GE(passes[1].time_jumps, 1.0);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bag_loop");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
