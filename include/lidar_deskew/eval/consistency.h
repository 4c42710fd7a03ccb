// How well consecutive scans agree in the fixed frame while the robot turns: a measure of a correction
// that needs no ground truth (real recordings).
#pragma once

#include <string>

#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::eval {

/// Scan-to-scan consistency in the fixed frame while turning, without ground truth: for consecutive
/// scans of `scan_topic` between which the base turned at least min_turn [rad], the mean distance of
/// each point of the later scan to the nearest point of the earlier one (pairs farther than max_pair
/// [m] are not counted: no overlap), for the raw scans and for their corrected versions on
/// `corrected_topic` (paired by header.seq). Smaller is more consistent. tf and the mount come from
/// the bag through the live node's rules (eval::loadRecordedTf).
struct ConsistencyReport {
  std::size_t turning_pairs = 0;
  double raw_mm = 0.0;        ///< mean nearest-neighbour distance, raw scans
  double corrected_mm = 0.0;  ///< the same, corrected scans
};
ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic,
                                     const ros_adapter::DeskewParams& params, double min_turn = 0.1,
                                     double max_pair = 0.3, const std::string& figure_csv = "");

}  // namespace lidar_deskew::eval
