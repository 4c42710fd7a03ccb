// The live cloud deskew (cloud_node.test: the nodelet lidar_deskew/PointCloudDeskew; cloud_node_plain.test:
// deskew_cloud_node) with a real roscore: UTM-30LX sweeps on a 6 m/s, 5 rad/s arc published as a
// driver's PointCloud2 (~layout: ouster | velodyne_last) on `points`, tf at 50 Hz on /tf; every cloud
// comes out on points_deskewed in the input's layout, stamped at its first point, on the true walls.
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
  const Drive drive;
  std::vector<sensor_msgs::PointCloud2::ConstPtr> outputs;
  ros::Subscriber output = nh.subscribe<sensor_msgs::PointCloud2>(
      "points_deskewed", 10,
      [&](const sensor_msgs::PointCloud2::ConstPtr& cloud) { outputs.push_back(cloud); });
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
    inputs.push_back(cloudOf(*drive.scanAt(t), layout));
    points.publish(inputs.back());
    publishTf(t + 0.02, t + 0.025 + 0.02);
    ros::WallDuration(0.01).sleep();
  }
  ASSERT_TRUE(waitFor([&] { return outputs.size() == inputs.size(); }, 10.0)) << outputs.size() << " outputs";
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const sensor_msgs::PointCloud2& out = *outputs[k];
    EXPECT_EQ(out.header.stamp, drive.stampOf(0.1 + k * 0.025));
    EXPECT_EQ(out.point_step, inputs[k]->point_step);
    EXPECT_EQ(out.width, inputs[k]->width);
    const std::vector<double> distances = drive.distances(returnsOf(out), out.header.stamp);
    EXPECT_EQ(distances.size(), returnsOf(*inputs[k]).size());
    EXPECT_LT(rms(distances), 1e-3);
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
