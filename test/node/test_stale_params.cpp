// Leftovers on the parameter server do not steer a launch (stale_params.test): wrong values are left
// in the namespaces of three nodes, as an earlier launch with `fixed_frame:=odm`, dynamic_reconfigure or
// a misspelt key in an old file leave them; then `roslaunch stale_params.launch` starts them through
// the real launch files against this roscore. Each node runs with config/deskew.yaml's values, the
// `params` file's over them, and nothing else; the nodelet corrects a scan timed as the file says.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <string>

#include "lidar_deskew/ros/deskew_params.h"
#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::DeskewParams;
using ros_adapter::NodeHandleParams;
using ros_adapter::TextParams;

/// [s] Outputs are stamped on whole microseconds.
constexpr double kStampTolerance = 20e-6;

std::string testParam(const std::string& name) {
  std::string value;
  ros::NodeHandle("~").getParam(name, value);
  return value;
}

/// `roslaunch FILE` as a child process, against this test's roscore (ROS_MASTER_URI is inherited);
/// stopped with SIGINT, as Ctrl-C stops it, when this goes away.
class Roslaunch {
 public:
  explicit Roslaunch(const std::string& file) : pid_(fork()) {
    if (pid_ == 0) {
      execlp("roslaunch", "roslaunch", file.c_str(), static_cast<char*>(nullptr));
      std::perror("roslaunch");
      _exit(127);
    }
  }
  ~Roslaunch() {
    if (pid_ <= 0)
      return;
    kill(pid_, SIGINT);
    int status = 0;
    for (int tenth = 0; tenth < 300; ++tenth) {  // roslaunch waits up to 15 s for its nodes' SIGINT
      if (waitpid(pid_, &status, WNOHANG) == pid_)
        return;
      usleep(100'000);
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, &status, 0);
  }
  Roslaunch(const Roslaunch&) = delete;
  Roslaunch& operator=(const Roslaunch&) = delete;
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_;
};

bool advertised(const std::string& topic) {
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  for (const auto& info : topics) {
    if (info.name == topic)
      return true;
  }
  return false;
}

/// The parameters a launch means: config/deskew.yaml, and over it the `params` file ("" = none).
DeskewParams meant(const std::string& params) {
  const DeskewParams defaults =
      DeskewParams::load(TextParams(ros_adapter::readParamFile(testParam("defaults"))));
  return params.empty() ? defaults
                        : DeskewParams::load(TextParams(ros_adapter::readParamFile(params)), defaults);
}

/// The parameters in `ns` on the server, as the node reads them; `names` gets the names found there.
DeskewParams onServer(const std::string& ns, std::vector<std::string>& names) {
  const ros::NodeHandle nh(ns);
  const NodeHandleParams source(nh);
  names = source.names();
  return DeskewParams::load(source);
}

void expectMeant(const std::string& ns, const DeskewParams& expected) {
  SCOPED_TRACE(ns);
  std::vector<std::string> names;
  const DeskewParams got = onServer(ns, names);
  EXPECT_EQ(got.fixed_frame, expected.fixed_frame);
  EXPECT_EQ(got.base_frame, expected.base_frame);
  EXPECT_EQ(got.deskew.reference, expected.deskew.reference);
  EXPECT_EQ(got.timing.stamp_at, expected.timing.stamp_at);
  EXPECT_EQ(got.timing.time_offset, expected.timing.time_offset);
  EXPECT_EQ(got.timing.use_scan_period, expected.timing.use_scan_period);
  EXPECT_EQ(got.timing.scan_period, expected.timing.scan_period);
  EXPECT_EQ(got.tf_timeout, expected.tf_timeout);
  EXPECT_EQ(got.cloud_time.field, expected.cloud_time.field);
  EXPECT_EQ(got.cloud_scan.height_min, expected.cloud_scan.height_min);
  // Nothing but parameters (and the diagnostics period the node itself writes for its Updater).
  names.erase(std::remove(names.begin(), names.end(), "diagnostic_period"), names.end());
  for (const std::string& unknown : DeskewParams::unknownNames(names))
    ADD_FAILURE() << "left over: ~" << unknown;
}

TEST(StaleParams, ALaunchSetsEveryParameterItMeans) {
  // Left by an earlier launch (fixed_frame:=odm, base_frame:=...), by dynamic_reconfigure (reference,
  // stamp_at, time_offset, scan_period, use_scan_period are written back to the server), and by a
  // misspelt key in an old file.
  const std::map<std::string, std::string> strings{{"fixed_frame", "odm"},
                                                   {"base_frame", "base_footprint"},
                                                   {"reference", "middle"},
                                                   {"stamp_at", "end"},
                                                   {"time_field", "bogus"}};
  const std::map<std::string, double> numbers{
      {"time_offset", 0.3}, {"scan_period", 0.2}, {"tf_timout", 1.0}, {"scan_height_min", 0.5}};
  for (const std::string ns : {"/stale_deskew", "/stale_node", "/stale_cloud"}) {
    for (const auto& [name, value] : strings)
      ros::param::set(ns + "/" + name, value);
    for (const auto& [name, value] : numbers)
      ros::param::set(ns + "/" + name, value);
    ros::param::set(ns + "/use_scan_period", true);
  }

  const Roslaunch launch(testParam("launch"));
  ASSERT_TRUE(launch.started());
  const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(30.0);
  while (!(advertised("/scan_deskewed") && advertised("/node_scan_deskewed") &&
           advertised("/points_deskewed")) &&
         ros::WallTime::now() < give_up)
    ros::WallDuration(0.1).sleep();
  // A node whose parameters are refused advertises nothing (the cloud's leftover band is empty).
  ASSERT_TRUE(advertised("/scan_deskewed"));
  ASSERT_TRUE(advertised("/node_scan_deskewed"));
  ASSERT_TRUE(advertised("/points_deskewed"));

  // deskew.launch with params:= deskew_calibrate's file for the Neato bag: its timing over the defaults.
  const std::string timing_file = testParam("timing");
  const DeskewParams timed = meant(timing_file);
  EXPECT_LT(timed.timing.time_offset, -0.05);  // the file's, not the leftover's or the default's
  expectMeant("/stale_deskew", timed);
  expectMeant("/stale_node", meant(""));
  expectMeant("/stale_cloud", meant(""));

  // The nodelet corrects a scan on the launch's frames and the file's timing: its first beam lies
  // time_offset before its stamp; the output is stamped at the first beam (reference: start).
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double t = 0.1;
  const double sweep = (rig.model.beams - 1) * rig.model.timeIncrement();
  rig.publishTfUntil(t);
  rig.publishScan(t, [&](sensor_msgs::LaserScan& scan) {
    scan.header.stamp = rig.stampOf(t - timed.timing.time_offset);
  });
  rig.publishTfUntil(t + sweep + 0.04);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(t), 10.0, scan, cloud, kStampTolerance));
  const double error = rms(cloudDistances(rig, *cloud));
  std::printf("after leftovers on the server: the scan corrected to %.2f mm RMS from the walls\n",
              1e3 * error);
  EXPECT_LT(error, 2e-3);
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_stale_params");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
