// The shape measure of a recording (core/scan_match.h; docs/CALIBRATION.md, "Shapes"): scans a short
// time apart whose turn differs, aligned by a free rigid scan match, raw against corrected under the
// parameters' timing; and whether tf's rotation between consecutive scans is the one the scans show.
// deskew_bag --consistency prints it.
#pragma once

#include <string>
#include <vector>

#include "lidar_deskew/core/scan_match.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::eval {

struct ShapeReport {
  std::size_t scans = 0;              ///< valid LaserScans of the topic that tf can take
  core::ShapeRatio shapes;            ///< corrected under params.timing and params.deskew
  core::RotationAgreement rotation;   ///< consecutive raw scans' matched rotation against tf's
  std::vector<std::string> warnings;  ///< core::shapeWarnings
};

/// Reads the LaserScans of `scan_topic` in `bag_path` (malformed ones and stamps tf cannot take left
/// out, as the node drops them) and the bag's tf and mount through the live node's rules
/// (eval::loadRecordedTf), and runs core::ShapeCheck. Throws std::runtime_error when the topic has
/// no scan or tf gives no mount.
ShapeReport measureShapes(const std::string& bag_path, const std::string& scan_topic,
                          const ros_adapter::DeskewParams& params,
                          const core::ShapeConfig& config = core::ShapeConfig());

/// "0.70 (quartiles 0.55-0.85; median aligned distance raw 12.3 mm, corrected 8.6 mm; 120 pairs)", or
/// "no pairs" .
std::string formatShapes(const core::ShapeRatio& shapes);
/// "0.98 (correlation 0.99; 300 pairs, 120 turning); best with tf read at the scans' times -10 ms: 0.99
/// (correlation 0.99)", or "no turning pairs (300 pairs)".
std::string formatRotation(const core::RotationAgreement& rotation);

}  // namespace lidar_deskew::eval
