#include "support/tf_tree.h"

#include <boost/make_shared.hpp>

#include <stdexcept>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::test {
namespace {

sim::Pose2 inverse(const sim::Pose2& pose) {
  const Eigen::Vector2d origin = pose.applyInverse({0.0, 0.0});
  return {origin.x(), origin.y(), -pose.yaw};
}

}  // namespace

TfTree TfTree::named(const std::string& name) {
  TfTree tree;
  if (name == "rep105") {  // a TurtleBot3: odom -> base_footprint moves, base_footprint -> base_link static
    tree.moving = "base_footprint";
    tree.base_offset = {0.05, 0.02, 0.1};  // not REP-105's usual pure z offset: a lever arm shows errors
  } else if (name == "plate") {
    tree.plate = "plate";
    tree.plate_offset = {0.1, -0.05, 0.3};
  } else if (name == "base") {
    tree.laser = "base_link";
  } else if (name == "slash") {
    tree.fixed = "/odom";
    tree.moving = tree.base = "/base_link";
    tree.laser = "/laser";
  } else if (name != "default") {
    throw std::invalid_argument("no tree " + name);
  }
  return tree;
}

geometry_msgs::TransformStamped stamped(const std::string& parent, const std::string& child,
                                        const ros::Time& stamp, const sim::Pose2& pose) {
  geometry_msgs::TransformStamped transform;
  transform.header.frame_id = parent;
  transform.header.stamp = stamp;
  transform.child_frame_id = child;
  transform.transform = ros_adapter::toTransform(
      mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0));
  return transform;
}

std::vector<geometry_msgs::TransformStamped> staticLinks(const TfTree& tree, const sim::Pose2& mount,
                                                         const ros::Time& stamp) {
  std::vector<geometry_msgs::TransformStamped> links;
  sim::Pose2 base_to_laser = mount;
  if (tree.base != tree.moving) {
    links.push_back(stamped(tree.moving, tree.base, stamp, tree.base_offset));
    base_to_laser = inverse(tree.base_offset).compose(mount);
  }
  if (tree.laser != tree.base) {
    if (tree.plate.empty()) {
      links.push_back(stamped(tree.base, tree.laser, stamp, base_to_laser));
    } else {
      links.push_back(stamped(tree.base, tree.plate, stamp, tree.plate_offset));
      links.push_back(
          stamped(tree.plate, tree.laser, stamp, inverse(tree.plate_offset).compose(base_to_laser)));
    }
  }
  return links;
}

sensor_msgs::LaserScan scanMessage(const sim::SimulatedScan& simulated, const std::string& frame) {
  sensor_msgs::LaserScan scan;
  scan.header.stamp = ros_adapter::toRosTime(simulated.scan.stamp);
  scan.header.frame_id = frame;
  scan.angle_min = simulated.scan.angle_min;
  scan.angle_max = simulated.scan.angle_max;
  scan.angle_increment = simulated.scan.angle_increment;
  scan.time_increment = simulated.scan.time_increment;
  scan.scan_time = simulated.scan.scan_time;
  scan.range_min = simulated.scan.range_min;
  scan.range_max = simulated.scan.range_max;
  scan.ranges = simulated.scan.ranges;
  scan.intensities = simulated.scan.intensities;
  return scan;
}

Drive::Drive(const TfTree& tree_in, const sim::LidarModel& model_in)
    : tree(tree_in), world(sim::World::demoRoom()), trajectory({-2.0, -1.0, 0.3}, 6.0, 5.0), model(model_in) {
  if (tree.laser == tree.base && tree.base == tree.moving)
    mount = {0.0, 0.0, 0.0};  // the laser is the base
}

ros::Time Drive::stampOf(double t) const {
  return ros_adapter::toRosTime(epoch + core::secondsToNs(t));
}

double Drive::secondsOf(const ros::Time& stamp) const {
  return core::nsToSeconds(ros_adapter::toNs(stamp) - epoch);
}

geometry_msgs::TransformStamped Drive::motionAt(double t) const {
  return stamped(tree.fixed, tree.moving, stampOf(t), trajectory.pose(t));
}

sensor_msgs::LaserScan::Ptr Drive::scanAt(double t) const {
  const sim::SimulatedScan simulated = sim::simulateScan(world, trajectory, mount, model, epoch, t);
  return boost::make_shared<sensor_msgs::LaserScan>(scanMessage(simulated, tree.laser));
}

double rms(const std::vector<double>& values) {
  return sim::errorStats(values).rms;
}

}  // namespace lidar_deskew::test
