// Writes a simulated recording as a ROS 1 bag, the way a real robot records one, plus its truth file.
#pragma once

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
};

/// Simulates `scenario` in its world and writes `bag_path` with
/// - /scan (sensor_msgs/LaserScan): stamped at the first beam (or as options.timing_fault says),
///   recorded at the scan's end (or at its stamp, if that is later);
/// - /tf (tf2_msgs/TFMessage): fixed -> base at tf_rate, the true pose (perfect odometry), from
///   tf_margin before the first scan to tf_margin after the last, both as the scans truly are and as
///   their (faulted) messages claim;
/// - /tf_static: base -> laser (the mount), once;
/// - /odom (nav_msgs/Odometry): the same poses with the commanded twist;
/// and the matching truth file at `truth_path` (with the fault and the true beam and sweep periods).
/// Throws on I/O errors, and std::invalid_argument for an invalid fault or a negative tf_margin.
void writeSimulationBag(const sim::Scenario& scenario, const SimBagOptions& options,
                        const std::string& bag_path, const std::string& truth_path);

}  // namespace lidar_deskew::sim
