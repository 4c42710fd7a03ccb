// Conversions between ROS 1 messages / tf2 and the ROS-free core.
#pragma once

#include <geometry_msgs/Transform.h>
#include <mrpt/poses/CPose3D.h>
#include <ros/time.h>
#include <sensor_msgs/LaserScan.h>

#include <string>

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

/// A frame id as tf2 looks it up: without a leading '/' (tf2_ros's MessageFilter does the same).
std::string normalizedFrame(const std::string& frame_id);

/// A number for messages, as short as it is exact to 6 digits ("0.2", "8", "1e-05").
std::string formatNumber(double value);

/// "x 0.100 y 0.000 z 0.200 m, yaw 0.0000 pitch 0.0000 roll 0.0000 rad": a pose for log lines.
std::string describePose(const mrpt::poses::CPose3D& pose);

/// Equal to 1e-9 in every entry of the homogeneous matrix: a re-published but unchanged transform.
bool samePose(const mrpt::poses::CPose3D& a, const mrpt::poses::CPose3D& b);

}  // namespace lidar_deskew::ros_adapter
