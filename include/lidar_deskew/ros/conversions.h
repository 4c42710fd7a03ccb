// Conversions between ROS 1 messages / tf2 and the ROS-free core.
#pragma once

#include <geometry_msgs/Transform.h>
#include <mrpt/poses/CPose3D.h>
#include <ros/time.h>
#include <sensor_msgs/LaserScan.h>

#include "lidar_deskew/core/scan.h"

namespace lidar_deskew::ros_adapter {

/// ros::Time -> [ns], and back.
inline core::TimeNs toNs(const ros::Time& time) {
  return static_cast<core::TimeNs>(time.toNSec());
}
inline ros::Time toRosTime(core::TimeNs time) {
  ros::Time result;
  result.fromNSec(static_cast<uint64_t>(time));
  return result;
}

/// The fields of a LaserScan the core needs (ranges and intensities copied).
core::PlanarScan fromMsg(const sensor_msgs::LaserScan& scan);

/// A tf transform (parent -> child) as an MRPT pose, through mrpt::ros1bridge.
mrpt::poses::CPose3D toPose(const geometry_msgs::Transform& transform);

/// An MRPT pose as a tf transform.
geometry_msgs::Transform toTransform(const mrpt::poses::CPose3D& pose);

}  // namespace lidar_deskew::ros_adapter
