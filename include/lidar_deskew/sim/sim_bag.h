// Writes a simulated recording as a ROS 1 bag, the way a real robot records one, plus its truth file.
#pragma once

#include <rosbag/bag.h>
#include <tf2_msgs/TFMessage.h>

#include <optional>
#include <string>

#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::sim {

struct SimBagOptions {
  bool noise = false;                              ///< add the LIDAR's Gaussian range noise
  unsigned seed = 1;                               ///< of the noise
  double tf_rate = 50.0;                           ///< [Hz] of /tf odom -> base_link and /odom
  core::TimeNs epoch = 1'700'000'000'000'000'000;  ///< [ns] bag time of t = 0
  std::string fixed_frame = "odom";
  std::string base_frame = "base_link";
  std::string laser_frame = "laser";
  std::string scan_topic = "/scan";
  /// How the /scan messages get the sensor's timing wrong (none by default); recorded in the truth.
  TimingFault timing_fault;
  /// [s] odometry starts this long before the first scan and ends this long after the last one.
  double tf_margin = 0.1;
  /// Relative error of the odometry per 20 ms step (sim::NoisyOdometry, its steps starting at the first
  /// odometry sample): 0 = perfect odometry, the true pose; 0.1 = each step's x, y and yaw increments
  /// off by 10 % (one sigma). The scans are unaffected (cast from the true pose, their noise drawn
  /// from their own generator).
  double odom_noise = 0.0;
  unsigned odom_noise_seed = 1;  ///< of the odometry's generator
  /// The odometry's yaw increments x this (sim::NoisyOdometry's yaw_scale): 1 = as true; 0.4 = a robot
  /// whose odometry reports 0.4 of its rotation. Recorded in the truth when not 1.
  double odom_yaw_scale = 1.0;
  /// The odometry samples as robots produce them (sim::OdometryTiming: stamp jitter, irregular rate,
  /// encoder ticks, late or bursty recording; none by default), drawn from a generator seeded with
  /// odom_noise_seed but apart from the noise's; recorded in the truth. Odometry then starts and ends
  /// jitter further out so that the stamps still cover the scans.
  OdometryTiming odom_timing;
  /// A recalibrated mount: /tf_static base -> laser written again, stamped and recorded at its time, and
  /// the scans whose last beam is at or after that time cast with it (recorded in the truth). Put the
  /// time between two sweeps (a sensor's blind sector, or between two beams) for a truth that holds
  /// for every beam of every scan.
  std::optional<MountChange> mount_change;
};

/// Simulates `scenario` in its world and writes `bag_path` with
/// - /scan (sensor_msgs/LaserScan): stamped at the first beam (or as options.timing_fault says),
///   recorded at the scan's end (or at its stamp, if that is later);
/// - /tf (tf2_msgs/TFMessage): fixed -> base at tf_rate, the odometry's pose (the true pose unless
///   options.odom_noise > 0), from tf_margin before the first scan to tf_margin after the last, both as
///   the scans truly are and as their (faulted) messages claim;
/// - /tf_static: base -> laser (the mount), once, latched (writeTfStatic); again at
///   options.mount_change's time with its mount;
/// - /odom (nav_msgs/Odometry): the same poses with the commanded twist (its speed and yaw rate times
///   the step's odometry factors);
/// and the matching truth file at `truth_path` (the true motion, the fault, the true beam and sweep
/// periods, the odometry noise and its seed).
/// Throws on I/O errors, and std::invalid_argument for an invalid fault, a negative tf_margin or
/// odom_noise, an invalid odom_timing.
void writeSimulationBag(const sim::Scenario& scenario, const SimBagOptions& options,
                        const std::string& bag_path, const std::string& truth_path);

/// Writes `transforms` on /tf_static at `time` as `rosbag record` records a latched topic (its
/// connection header says "latching: 1"), so that `rosbag play` latches it: a node started during the
/// replay gets the mount at once.
void writeTfStatic(rosbag::Bag& bag, const ros::Time& time, const tf2_msgs::TFMessage& transforms);

}  // namespace lidar_deskew::sim
