// The plain nodes' main: one DeskewNode, spun until shutdown; an invalid parameter ends it with 1.
#pragma once

#include <ros/ros.h>

#include "lidar_deskew/node/laser_scan_deskew_node.h"

namespace lidar_deskew::node {

template <class Node>
int runNode(int argc, char** argv, const char* default_name) {
  ros::init(argc, argv, default_name);
  ros::NodeHandle nh, private_nh("~");
  try {
    Node node(nh, private_nh, ros::this_node::getName());
    ros::spin();
  } catch (const core::InvalidInput& error) {
    ROS_FATAL("%s: invalid parameter %s", ros::this_node::getName().c_str(), error.what());
    return 1;
  }
  return 0;
}

}  // namespace lidar_deskew::node
