#include "lidar_deskew/ros/conversions.h"

#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/ros1bridge/pose.h>
#include <tf2/LinearMath/Transform.h>
#include <Eigen/Dense>

#include <cstdio>

namespace lidar_deskew::ros_adapter {

core::PlanarScan fromMsg(const sensor_msgs::LaserScan& scan) {
  core::PlanarScan planar;
  planar.stamp = toNs(scan.header.stamp);
  planar.angle_min = scan.angle_min;
  planar.angle_max = scan.angle_max;
  planar.angle_increment = scan.angle_increment;
  planar.time_increment = scan.time_increment;
  planar.scan_time = scan.scan_time;
  planar.range_min = scan.range_min;
  planar.range_max = scan.range_max;
  planar.ranges = scan.ranges;
  planar.intensities = scan.intensities;
  return planar;
}

mrpt::poses::CPose3D toPose(const geometry_msgs::Transform& transform) {
  const tf2::Transform tf_transform(
      tf2::Quaternion(transform.rotation.x, transform.rotation.y, transform.rotation.z, transform.rotation.w),
      tf2::Vector3(transform.translation.x, transform.translation.y, transform.translation.z));
  return mrpt::ros1bridge::fromROS(tf_transform);
}

geometry_msgs::Transform toTransform(const mrpt::poses::CPose3D& pose) {
  const tf2::Transform tf_transform = mrpt::ros1bridge::toROS_tfTransform(pose);
  geometry_msgs::Transform transform;
  transform.translation.x = tf_transform.getOrigin().x();
  transform.translation.y = tf_transform.getOrigin().y();
  transform.translation.z = tf_transform.getOrigin().z();
  const tf2::Quaternion rotation = tf_transform.getRotation();
  transform.rotation.x = rotation.x();
  transform.rotation.y = rotation.y();
  transform.rotation.z = rotation.z();
  transform.rotation.w = rotation.w();
  return transform;
}

std::string normalizedFrame(const std::string& frame_id) {
  return !frame_id.empty() && frame_id.front() == '/' ? frame_id.substr(1) : frame_id;
}

std::string formatNumber(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

std::string describePose(const mrpt::poses::CPose3D& pose) {
  char text[128];
  std::snprintf(text, sizeof text, "x %.3f y %.3f z %.3f m, yaw %.4f pitch %.4f roll %.4f rad", pose.x(),
                pose.y(), pose.z(), pose.yaw(), pose.pitch(), pose.roll());
  return text;
}

bool samePose(const mrpt::poses::CPose3D& a, const mrpt::poses::CPose3D& b) {
  // The matrices held here: an `auto` Eigen expression of the temporaries read them after they were
  // gone (ASan in fuzz_messages, through TfFeed::mount).
  const auto matrix_a = a.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
  const auto matrix_b = b.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
  return (matrix_a.asEigen() - matrix_b.asEigen()).cwiseAbs().maxCoeff() <= 1e-9;
}

}  // namespace lidar_deskew::ros_adapter
