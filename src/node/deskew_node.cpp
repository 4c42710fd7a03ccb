// deskew_node: the live deskew as a plain node, for robots without a nodelet manager.
#include <ros/ros.h>

#include "lidar_deskew/node/laser_scan_deskew_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "lidar_deskew");
  ros::NodeHandle nh, private_nh("~");
  try {
    lidar_deskew::node::LaserScanDeskewNode node(nh, private_nh, ros::this_node::getName());
    ros::spin();
  } catch (const lidar_deskew::core::InvalidInput& error) {
    ROS_FATAL("%s: invalid parameter %s", ros::this_node::getName().c_str(), error.what());
    return 1;
  }
  return 0;
}
