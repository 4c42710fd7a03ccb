// The launch files as users call them (launch_files.test): two instances on two scans publish on
// outputs named after their inputs, never on one topic; a `params:=` file is layered over
// config/deskew.yaml, an argument given on the command line wins over both. A plain node given an
// invalid value ends with status 1.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <string>

namespace lidar_deskew::test {
namespace {

std::map<std::string, std::string> advertisedTopics() {
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  std::map<std::string, std::string> types;
  for (const auto& topic : topics)
    types[topic.name] = topic.datatype;
  return types;
}

TEST(LaunchFiles, TwoInstancesPublishOnOutputsNamedAfterTheirInputs) {
  std::map<std::string, std::string> topics;
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(20.0);
  while (ros::WallTime::now() < end) {
    topics = advertisedTopics();
    if (topics.count("/rear_scan_deskewed_points") && topics.count("/front_scan_deskewed_points") &&
        topics.count("/stable_scan_deskewed_points"))
      break;
    ros::WallDuration(0.1).sleep();
  }
  EXPECT_EQ(topics["/front_scan_deskewed"], "sensor_msgs/LaserScan");
  EXPECT_EQ(topics["/front_scan_deskewed_points"], "sensor_msgs/PointCloud2");
  EXPECT_EQ(topics["/rear_scan_deskewed"], "sensor_msgs/LaserScan");
  // The node with deskew_calibrate's file started (a bad value would have stopped it first).
  EXPECT_EQ(topics["/stable_scan_deskewed"], "sensor_msgs/LaserScan");
  EXPECT_EQ(topics["/rear_scan_deskewed_points"], "sensor_msgs/PointCloud2");
  EXPECT_EQ(topics.count("/scan_deskewed"), 0u);
}

TEST(LaunchFiles, ParamsFileOverDefaultsAndArgumentsOverTheFile) {
  std::string value;
  // front_deskew: params:=launch_params.yaml (base_frame base_footprint, stamp_at end), reference:=middle
  ASSERT_TRUE(ros::param::get("/front_deskew/base_frame", value));
  EXPECT_EQ(value, "base_footprint");  // the file, not the launch default
  ASSERT_TRUE(ros::param::get("/front_deskew/stamp_at", value));
  EXPECT_EQ(value, "end");
  ASSERT_TRUE(ros::param::get("/front_deskew/reference", value));
  EXPECT_EQ(value, "middle");  // the argument, over the file's "start"
  ASSERT_TRUE(ros::param::get("/front_deskew/fixed_frame", value));
  EXPECT_EQ(value, "odom");  // neither in the file nor given: config/deskew.yaml's, under the file
  // neato_deskew: deskew_calibrate's file; the node took it (it advertised its outputs).
  double offset = 0.0;
  ASSERT_TRUE(ros::param::get("/neato_deskew/time_offset", offset));
  EXPECT_LT(offset, -0.05);  // the Neato's first beam lies about 0.1 s before its stamp
  EXPECT_GT(offset, -0.2);
  ASSERT_TRUE(ros::param::get("/neato_deskew/beam_order", value));
  EXPECT_EQ(value, "as_message");
  // rear_deskew: the default file, stamp_at:=end on the command line.
  ASSERT_TRUE(ros::param::get("/rear_deskew/stamp_at", value));
  EXPECT_EQ(value, "end");
  ASSERT_TRUE(ros::param::get("/rear_deskew/base_frame", value));
  EXPECT_EQ(value, "base_link");
}

/// The plain nodes' main (node::runLiveNode): an invalid parameter is a FATAL line naming it, and the
/// process ends with status 1 (what roslaunch reports, and respawn sees), for either node.
TEST(LaunchFiles, AnInvalidParameterEndsAPlainNodeWithStatusOne) {
  // The nodes lie beside this test in the devel space.
  char self[4096];
  const ssize_t length = readlink("/proc/self/exe", self, sizeof self - 1);
  ASSERT_GT(length, 0);
  const std::string here = std::string(self, static_cast<std::size_t>(length));
  const std::string folder = here.substr(0, here.rfind('/') + 1);
  const struct {
    const char* node;
    const char* parameter;
    const char* said;
  } cases[] = {
      {"deskew_node", "_reference:=sideways",
       "invalid parameter reference: must be one of start|middle|end, got 'sideways'"},
      {"deskew_cloud_node", "_interpolation:=cubic",
       "invalid parameter interpolation: must be one of twist|linear, got 'cubic'"},
  };
  for (const auto& invalid : cases) {
    // `timeout`: a node that took the value would spin until killed (status 124).
    const std::string command = "timeout 30 " + folder + invalid.node + " __name:=invalid_" + invalid.node +
                                " " + invalid.parameter + " 2>&1";
    FILE* process = popen(command.c_str(), "r");
    ASSERT_NE(process, nullptr);
    std::string output;
    char buffer[512];
    while (std::fgets(buffer, sizeof buffer, process))
      output += buffer;
    const int status = pclose(process);
    ASSERT_TRUE(WIFEXITED(status)) << command;
    EXPECT_EQ(WEXITSTATUS(status), 1) << command << "\n" << output;
    EXPECT_NE(output.find("FATAL"), std::string::npos) << output;
    EXPECT_NE(output.find(invalid.said), std::string::npos) << output;
  }
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_launch_files");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
