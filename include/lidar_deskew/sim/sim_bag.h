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
};

/// Simulates `scenario` and writes `bag_path` with
/// - /scan (sensor_msgs/LaserScan): stamped at the first beam, recorded at the scan's end;
/// - /tf (tf2_msgs/TFMessage): fixed -> base at tf_rate, the true pose (perfect odometry), from
///   0.1 s before the first scan to 0.1 s after the last;
/// - /tf_static: base -> laser (the mount), once;
/// - /odom (nav_msgs/Odometry): the same poses with the commanded twist;
/// and the matching truth file at `truth_path`. Throws on I/O errors.
void writeSimulationBag(const sim::Scenario& scenario, const SimBagOptions& options,
                        const std::string& bag_path, const std::string& truth_path);

}  // namespace lidar_deskew::sim
