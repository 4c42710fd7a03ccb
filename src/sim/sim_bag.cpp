#include "lidar_deskew/sim/sim_bag.h"

#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

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

void writeTfStatic(rosbag::Bag& bag, const ros::Time& time, const tf2_msgs::TFMessage& transforms) {
  using Traits = ros::message_traits::DataType<tf2_msgs::TFMessage>;
  auto header = boost::make_shared<ros::M_string>();
  (*header)["callerid"] = "/lidar_deskew_simulator";
  (*header)["latching"] = "1";
  (*header)["topic"] = "/tf_static";
  (*header)["type"] = Traits::value();
  (*header)["md5sum"] = ros::message_traits::MD5Sum<tf2_msgs::TFMessage>::value();
  (*header)["message_definition"] = ros::message_traits::Definition<tf2_msgs::TFMessage>::value();
  bag.write("/tf_static", time, transforms, header);
}

void writeSimulationBag(const sim::Scenario& scenario, const SimBagOptions& options,
                        const std::string& bag_path, const std::string& truth_path) {
  const sim::TimingFault& fault = options.timing_fault;
  fault.validate();
  if (!(options.tf_margin >= 0.0) || !std::isfinite(options.tf_margin))
    throw std::invalid_argument("tf_margin: must be finite and >= 0");
  const sim::PiecewiseTrajectory trajectory = scenario.trajectory();
  const sim::World& world = scenario.world;
  const double scan_period = 1.0 / scenario.lidar.rate;
  const core::TimeNs epoch = options.epoch;
  const auto at = [&](double t) { return epoch + core::secondsToNs(t); };
  // The beam times a faulted message claims, relative to the true earliest beam: from stamp_error to
  // stamp_error + claimed sweep. Odometry covers them too, so a tool may read the scans as stamped.
  const double claimed_sweep = fault.time_increment_factor *
                               static_cast<double>(scenario.lidar.timeIncrement()) *
                               (scenario.lidar.beams - 1);
  const double claimed_before = std::max(0.0, -fault.stamp_error);
  const double claimed_after = std::max(0.0, fault.stamp_error + claimed_sweep - scan_period);

  // Odometry from tf_margin before the first scan to tf_margin after the last scan's end (as true or
  // as claimed, whichever is further out), its samples on multiples of 1 / tf_rate since t = 0.
  const double tf_begin =
      -std::ceil((options.tf_margin + claimed_before) * options.tf_rate - 1e-9) / options.tf_rate;
  const double tf_end = scenario.duration + scan_period + claimed_after + options.tf_margin;
  const sim::OdometryTiming& timing = options.odom_timing;
  const long tf_samples = std::lround(std::floor((tf_end - tf_begin) * options.tf_rate));
  // In the order a recorder writes them (throws for a bad odom_noise or odom_timing).
  const std::vector<sim::OdometrySample> samples =
      sim::recordOdometry(trajectory, tf_begin, tf_samples, tf_end, options.tf_rate, options.odom_noise,
                          options.odom_noise_seed, options.odom_yaw_scale, timing);
  const std::size_t n_samples = samples.size();

  rosbag::Bag bag(bag_path, rosbag::bagmode::Write);

  // The mount first, at the earliest odometry stamp (tf_begin unless the stamps jitter).
  double static_time = tf_begin;
  for (const sim::OdometrySample& sample : samples)
    static_time = std::min(static_time, sample.stamp);
  tf2_msgs::TFMessage static_transforms;
  static_transforms.transforms.push_back(
      stamped(options.base_frame, options.laser_frame, at(static_time), scenario.mount));
  writeTfStatic(bag, toRosTime(at(static_time)), static_transforms);

  const auto writeOdometry = [&](const sim::OdometrySample& sample) {
    tf2_msgs::TFMessage transforms;
    transforms.transforms.push_back(
        stamped(options.fixed_frame, options.base_frame, at(sample.stamp), sample.pose));
    bag.write("/tf", toRosTime(at(sample.record)), transforms);

    nav_msgs::Odometry odometry;
    odometry.header = transforms.transforms[0].header;
    odometry.child_frame_id = options.base_frame;
    const geometry_msgs::Transform& pose = transforms.transforms[0].transform;
    odometry.pose.pose.position.x = pose.translation.x;
    odometry.pose.pose.position.y = pose.translation.y;
    odometry.pose.pose.position.z = pose.translation.z;
    odometry.pose.pose.orientation = pose.rotation;
    odometry.twist.twist.linear.x = sample.speed;
    odometry.twist.twist.angular.z = sample.yaw_rate;
    bag.write("/odom", toRosTime(at(sample.record)), odometry);
  };

  const std::optional<MountChange>& change = options.mount_change;
  if (change && !std::isfinite(change->time))
    throw std::invalid_argument("mount_change: its time must be finite");
  bool mount_changed = false;
  const auto writeMountChange = [&] {
    tf2_msgs::TFMessage transforms;
    transforms.transforms.push_back(
        stamped(options.base_frame, options.laser_frame, at(change->time), change->mount));
    writeTfStatic(bag, toRosTime(at(change->time)), transforms);
    mount_changed = true;
  };

  std::mt19937 rng(options.seed);
  const auto writeScan = [&](int k) {
    const double start_time = k * scan_period;
    // The mount in force at the sweep's last beam.
    const bool changed = change && start_time + scenario.lidar.sweepDuration() >= change->time;
    const sim::SimulatedScan simulated =
        sim::simulateScan(world, trajectory, changed ? change->mount : scenario.mount, scenario.lidar, epoch,
                          start_time, options.noise ? &rng : nullptr, fault);
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
    // A driver publishes the scan once its last beam is measured (never before the stamp it gives it).
    bag.write(options.scan_topic, toRosTime(std::max(at(start_time + scan_period), planar.stamp)), scan);
  };

  // Written in time order, as a recorder does (readers then go through the file once).
  const int scans = static_cast<int>(std::ceil(scenario.duration / scan_period - 1e-9));
  std::size_t next_odometry = 0;
  const auto odometryRecord = [&](std::size_t j) { return samples[j].record; };
  for (int k = 0; k < scans; ++k) {
    // When the scan is recorded [s]: see writeScan.
    const double recorded = std::max((k + 1) * scan_period, k * scan_period + fault.stamp_error);
    while (next_odometry < n_samples && odometryRecord(next_odometry) <= recorded) {
      if (change && !mount_changed && change->time < odometryRecord(next_odometry))
        writeMountChange();
      writeOdometry(samples[next_odometry++]);
    }
    if (change && !mount_changed && change->time < recorded)
      writeMountChange();  // before the scan recorded after it (after one recorded at its time)
    writeScan(k);
  }
  while (next_odometry < n_samples) {
    if (change && !mount_changed && change->time < odometryRecord(next_odometry))
      writeMountChange();
    writeOdometry(samples[next_odometry++]);
  }
  if (change && !mount_changed)
    writeMountChange();
  bag.close();

  sim::Truth truth;
  truth.scenario = scenario.name;
  truth.epoch = epoch;
  truth.range_sigma = options.noise ? scenario.lidar.range_sigma : 0.0;
  truth.mount = scenario.mount;
  truth.mount_change = change;
  truth.start = scenario.start;
  truth.pieces = scenario.pieces;
  truth.world = world;
  truth.timing_fault = fault;
  truth.beam_period = static_cast<double>(scenario.lidar.timeIncrement());
  truth.sweep_period = scan_period;
  truth.odom_noise = options.odom_noise;
  truth.odom_noise_seed = options.odom_noise_seed;
  truth.odom_yaw_scale = options.odom_yaw_scale;
  truth.odom_timing = timing;
  sim::writeTruth(truth, truth_path);
}

}  // namespace lidar_deskew::sim
