// How well overlapping scans of a recording agree in the fixed frame, raw and corrected: the measure
// of a correction that needs no ground truth (real recordings), shared by deskew_bag --consistency,
// the demo and deskew_calibrate (core/consistency.h; docs/CALIBRATION.md).
#pragma once

#include <string>

#include "lidar_deskew/core/consistency.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::eval {

/// The robust point-to-line distance (core::pairDistance) over every overlapping pair of scans
/// (core::overlappingPairs: up to 8 earlier partners per scan within 10 s and 3 m), for the raw
/// scans of `scan_topic` (every beam at header.stamp) and for their corrected versions on
/// `corrected_topic` (paired by stamp and order: each raw scan with the corrected one stamped at its
/// reference time under `params`, in its frame; placed at their own stamp, the reference time); the same
/// pairs for both, chosen on the corrected scans. Also over the pairs in which either scan turns at
/// `turning_rate` [rad/s] or faster. tf and the mount come from the bag through the live node's rules
/// (eval::loadRecordedTf). Smaller is more consistent.
struct ConsistencyReport {
  core::ConsistencySummary raw, corrected;                  ///< every overlapping pair [m]
  core::ConsistencySummary raw_turning, corrected_turning;  ///< pairs with a turning scan [m]
};
ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic,
                                     const ros_adapter::DeskewParams& params, double turning_rate = 0.3,
                                     const std::string& figure_csv = "");

/// "12.3 mm (spread 4.5, 310 pairs)".
std::string formatConsistency(const core::ConsistencySummary& summary);

}  // namespace lidar_deskew::eval
