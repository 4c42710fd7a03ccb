// Offline reprocessing of recorded bags (deskew_bag): the same parameters, ScanProcessor and tf adapter
// as the live node, tf read from the bag itself. No roscore needed.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "lidar_deskew/ros/bag_tf.h"
#include "lidar_deskew/ros/params.h"

namespace lidar_deskew::ros_adapter {

struct BagDeskewOptions {
  std::string input;
  std::string output;
  std::vector<std::string> scan_topics{"/scan"};
  /// Put the corrected LaserScan on the original topic and keep the raw one as <topic>_raw.
  bool replace = false;
  MountSource mount_from = MountSource::kTfStatic;
  std::string compression = "none";  ///< of the output: none, bz2 or lz4
  DeskewParams params;
  /// Called now and then with the fraction done [0, 1] and scans corrected so far.
  std::function<void(double fraction, std::size_t scans)> progress;
  /// Receives notes for the user (which mount was used, conflicts).
  std::function<void(const std::string&)> inform;
};

struct BagDeskewSummary {
  std::size_t messages = 0;  ///< messages copied from the input
  std::size_t scans = 0;     ///< scan messages on the scan topics
  std::size_t corrected = 0;
  std::size_t passed_through = 0;  ///< on_tf_failure: pass_through
  std::size_t dropped_invalid = 0;
  std::size_t dropped_tf = 0;
  std::string mount;  ///< which mount was used, in words
};

/// Reprocesses options.input into options.output: every input message unchanged, plus for each scan
/// topic <topic>_deskewed (LaserScan) and <topic>_deskewed_points (PointCloud2); or, with replace, the
/// corrected scan on <topic> and the raw one on <topic>_raw. Writes a temporary file beside the output
/// and renames it at the end, so no partial output is ever left. Throws std::runtime_error with a
/// message for the user: unreadable or corrupt input, output = input, no tf between the frames
/// (naming them), invalid options.
BagDeskewSummary deskewBag(const BagDeskewOptions& options);

/// Scan-to-scan consistency in the fixed frame while turning, without ground truth: for consecutive
/// scans of `scan_topic` between which the base turned at least min_turn [rad], the mean distance of
/// each point of the later scan to the nearest point of the earlier one (pairs farther than max_pair
/// [m] are not counted: no overlap), for the raw scans and for their corrected versions on
/// `corrected_topic` (paired by header.seq). Smaller is more consistent.
struct ConsistencyReport {
  std::size_t turning_pairs = 0;
  double raw_mm = 0.0;        ///< mean nearest-neighbour distance, raw scans
  double corrected_mm = 0.0;  ///< the same, corrected scans
};
ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic, const DeskewParams& params,
                                     MountSource mount_from, double min_turn = 0.1, double max_pair = 0.3,
                                     const std::string& figure_csv = "");

}  // namespace lidar_deskew::ros_adapter
