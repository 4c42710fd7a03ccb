#include "lidar_deskew/sim/sim_bag.h"

#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <random>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::sim {
namespace {

using ros_adapter::toRosTime;
using ros_adapter::toTransform;

mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose) {
  return mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0);
}

geometry_msgs::TransformStamped stamped(const std::string& parent, const std::string& child,
                                        core::TimeNs time, const sim::Pose2& pose) {
  geometry_msgs::TransformStamped transform;
  transform.header.frame_id = parent;
  transform.header.stamp = toRosTime(time);
  transform.child_frame_id = child;
  transform.transform = toTransform(toMrpt(pose));
  return transform;
}

}  // namespace

void writeSimulationBag(const sim::Scenario& scenario, const SimBagOptions& options,
                        const std::string& bag_path, const std::string& truth_path) {
  const sim::PiecewiseTrajectory trajectory = scenario.trajectory();
  const sim::World world = sim::World::hall();
  const double scan_period = 1.0 / scenario.lidar.rate;
  const core::TimeNs epoch = options.epoch;
  const auto at = [&](double t) { return epoch + core::secondsToNs(t); };

  rosbag::Bag bag(bag_path, rosbag::bagmode::Write);

  tf2_msgs::TFMessage static_transforms;
  static_transforms.transforms.push_back(
      stamped(options.base_frame, options.laser_frame, at(-0.1), scenario.mount));
  bag.write("/tf_static", toRosTime(at(-0.1)), static_transforms);

  // Odometry from 0.1 s before the first scan to 0.1 s after the last scan's end.
  const double tf_begin = -0.1;
  const double tf_end = scenario.duration + scan_period + 0.1;
  const long tf_samples = std::lround(std::floor((tf_end - tf_begin) * options.tf_rate));
  const auto tfTime = [&](long k) { return tf_begin + static_cast<double>(k) / options.tf_rate; };
  const auto writeOdometry = [&](long k) {
    const double t = tfTime(k);
    tf2_msgs::TFMessage transforms;
    transforms.transforms.push_back(
        stamped(options.fixed_frame, options.base_frame, at(t), trajectory.pose(t)));
    bag.write("/tf", toRosTime(at(t)), transforms);

    nav_msgs::Odometry odometry;
    odometry.header = transforms.transforms[0].header;
    odometry.child_frame_id = options.base_frame;
    const geometry_msgs::Transform& pose = transforms.transforms[0].transform;
    odometry.pose.pose.position.x = pose.translation.x;
    odometry.pose.pose.position.y = pose.translation.y;
    odometry.pose.pose.position.z = pose.translation.z;
    odometry.pose.pose.orientation = pose.rotation;
    odometry.twist.twist.linear.x = trajectory.speed(t);
    odometry.twist.twist.angular.z = trajectory.yawRate(t);
    bag.write("/odom", toRosTime(at(t)), odometry);
  };

  std::mt19937 rng(options.seed);
  const auto writeScan = [&](int k) {
    const double start_time = k * scan_period;
    const sim::SimulatedScan simulated = sim::simulateScan(world, trajectory, scenario.mount, scenario.lidar,
                                                           epoch, start_time, options.noise ? &rng : nullptr);
    const core::PlanarScan& planar = simulated.scan;
    sensor_msgs::LaserScan scan;
    scan.header.seq = static_cast<uint32_t>(k);
    scan.header.stamp = toRosTime(planar.stamp);
    scan.header.frame_id = options.laser_frame;
    scan.angle_min = planar.angle_min;
    scan.angle_max = planar.angle_max;
    scan.angle_increment = planar.angle_increment;
    scan.time_increment = planar.time_increment;
    scan.scan_time = planar.scan_time;
    scan.range_min = planar.range_min;
    scan.range_max = planar.range_max;
    scan.ranges = planar.ranges;
    // A driver publishes the scan once its last beam is measured.
    bag.write(options.scan_topic, toRosTime(at(start_time + scan_period)), scan);
  };

  // Written in time order, as a recorder does (readers then go through the file once).
  const int scans = static_cast<int>(std::ceil(scenario.duration / scan_period - 1e-9));
  long next_odometry = 0;
  for (int k = 0; k < scans; ++k) {
    while (next_odometry <= tf_samples && tfTime(next_odometry) <= (k + 1) * scan_period)
      writeOdometry(next_odometry++);
    writeScan(k);
  }
  while (next_odometry <= tf_samples)
    writeOdometry(next_odometry++);
  bag.close();

  sim::Truth truth;
  truth.scenario = scenario.name;
  truth.epoch = epoch;
  truth.range_sigma = options.noise ? scenario.lidar.range_sigma : 0.0;
  truth.mount = scenario.mount;
  truth.start = scenario.start;
  truth.pieces = scenario.pieces;
  truth.world = world;
  sim::writeTruth(truth, truth_path);
}

}  // namespace lidar_deskew::sim
