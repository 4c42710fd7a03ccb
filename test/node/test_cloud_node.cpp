// The live cloud deskew (cloud_node.test: the nodelet lidar_deskew/PointCloudDeskew through
// deskew_cloud.launch and its arguments; cloud_node_plain.test: deskew_cloud_node with its defaults)
// with a real roscore: UTM-30LX sweeps on a 6 m/s, 5 rad/s arc published as a driver's PointCloud2
// (~layout: ouster | velodyne_last) on `points`, tf at 50 Hz on /tf; every cloud comes out on
// points_deskewed in the input's layout, stamped at its first point (~reference: start) or its last
// return (end), on the true walls. ~time_offset [s]: the clouds are stamped that much early, which the
// node's time_offset (set to it by the launch) must put right. ~cloud_scan: points_deskewed_scan comes
// with each cloud, its intensities those of the points it keeps. ~node with ~scan_height_min/max: the
// node's parameters are the launch arguments.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>

#include "support/driver_clouds.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {
namespace {

TEST(CloudNode, EveryCloudIsCorrectedOntoTheTrueWalls) {
  ros::NodeHandle nh, private_nh("~");
  const Layout layout =
      private_nh.param<std::string>("layout", "ouster") == "ouster" ? Layout::kOuster : Layout::kVelodyneLast;
  const double time_offset = private_nh.param("time_offset", 0.0);
  const bool reference_end = private_nh.param<std::string>("reference", "start") == "end";
  const bool cloud_scan = private_nh.param("cloud_scan", false);
  const Drive drive;
  std::vector<sensor_msgs::PointCloud2::ConstPtr> outputs;
  ros::Subscriber output = nh.subscribe<sensor_msgs::PointCloud2>(
      "points_deskewed", 10,
      [&](const sensor_msgs::PointCloud2::ConstPtr& cloud) { outputs.push_back(cloud); });
  std::vector<sensor_msgs::LaserScan::ConstPtr> scans;
  ros::Subscriber scan_output = nh.subscribe<sensor_msgs::LaserScan>(
      "points_deskewed_scan", 10,
      [&](const sensor_msgs::LaserScan::ConstPtr& scan) { scans.push_back(scan); });
  const std::string node = private_nh.param<std::string>("node", "");
  for (const char* name : {"scan_height_min", "scan_height_max"}) {
    double expected = 0.0, set = 0.0;
    if (!node.empty() && private_nh.getParam(name, expected)) {
      EXPECT_TRUE(nh.getParam(node + "/" + name, set)) << name;
      EXPECT_EQ(set, expected) << name;
    }
  }
  ros::Publisher points = nh.advertise<sensor_msgs::PointCloud2>("points", 10);
  ros::Publisher tf = nh.advertise<tf2_msgs::TFMessage>("/tf", 100);
  ros::Publisher tf_static = nh.advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
  const auto waitFor = [](const std::function<bool()>& done, double seconds) {
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(seconds);
    while (!done() && ros::WallTime::now() < until) {
      ros::spinOnce();
      ros::WallDuration(0.005).sleep();
    }
    return done();
  };
  // Lazy: the node subscribes to points once its output has a subscriber.
  ASSERT_TRUE(waitFor([&] { return points.getNumSubscribers() > 0 && tf.getNumSubscribers() > 0; }, 10.0));
  tf2_msgs::TFMessage statics;
  statics.transforms = drive.statics();
  tf_static.publish(statics);
  const auto publishTf = [&](double from, double to) {
    for (double t = from; t <= to + 1e-9; t += 0.02) {
      tf2_msgs::TFMessage message;
      message.transforms = {drive.motionAt(t)};
      tf.publish(message);
    }
  };
  publishTf(-0.1, 0.1);
  std::vector<sensor_msgs::PointCloud2::ConstPtr> inputs;
  for (int k = 0; k < 4; ++k) {
    const double t = 0.1 + k * 0.025;
    const sensor_msgs::PointCloud2::Ptr cloud = cloudOf(*drive.scanAt(t), layout);
    cloud->header.stamp -= ros::Duration(time_offset);
    inputs.push_back(cloud);
    points.publish(cloud);
    publishTf(t + 0.02, t + 0.025 + 0.02);
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_TRUE(waitFor(
      [&] { return outputs.size() == inputs.size() && (!cloud_scan || scans.size() == inputs.size()); },
      10.0))
      << outputs.size() << " outputs, " << scans.size() << " scans";
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const sensor_msgs::PointCloud2& out = *outputs[k];
    const sensor_msgs::LaserScan::Ptr scan = drive.scanAt(0.1 + k * 0.025);
    std::size_t last_return = 0;
    for (std::size_t i = 0; i < scan->ranges.size(); ++i)
      last_return = std::isfinite(scan->ranges[i]) ? i : last_return;
    const double reference =
        0.1 + k * 0.025 + (reference_end ? last_return * static_cast<double>(scan->time_increment) : 0.0);
    EXPECT_NEAR((out.header.stamp - drive.stampOf(reference)).toSec(), 0.0, 1e-6);
    EXPECT_EQ(out.point_step, inputs[k]->point_step);
    EXPECT_EQ(out.width, inputs[k]->width);
    const std::vector<double> distances = drive.distances(returnsOf(out), out.header.stamp);
    EXPECT_EQ(distances.size(), returnsOf(*inputs[k]).size());
    EXPECT_LT(rms(distances), 1e-3);
    if (!cloud_scan)
      continue;
    // The planar scan: each filled bin's intensity (100 + the beam's index) names the point it keeps.
    const sensor_msgs::LaserScan& planar = *scans[k];
    EXPECT_EQ(planar.header.stamp, out.header.stamp);
    ASSERT_EQ(planar.intensities.size(), planar.ranges.size());
    const std::vector<Xy> returns = returnsOf(out);
    std::size_t filled = 0;
    for (std::size_t bin = 0; bin < planar.ranges.size(); ++bin) {
      if (!std::isfinite(planar.ranges[bin]))
        continue;
      ++filled;
      const auto beam = static_cast<std::size_t>(std::lround(planar.intensities[bin]) - 100);
      ASSERT_LT(beam, out.width);  // Ouster's layout: point i is beam i
      EXPECT_NEAR(planar.ranges[bin], std::hypot(floatAt(out, beam, 0), floatAt(out, beam, 4)), 1e-4) << bin;
    }
    EXPECT_GT(filled, 500u);
  }
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_cloud_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
