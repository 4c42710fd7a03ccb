// Offline reprocessing of recorded bags (deskew_bag): every message of the bag fed in record-time order
// into the live node's ros_adapter::ScanPipeline, so tf arrives after a scan as it did live and a
// scan waits until the bag's later tf covers its last beam (docs/DESIGN.md §2). No roscore needed.
#pragma once

#include <rosbag/bag.h>

#include <atomic>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/scan_pipeline.h"

namespace lidar_deskew::bag {

struct BagDeskewOptions {
  std::string input;
  std::string output;
  /// Topics to correct; empty: the bag's LaserScan topics (BagDeskewSummary::chosen_topics says which).
  std::vector<std::string> scan_topics;
  /// PointCloud2 topics to correct (per-point time fields: docs/DESIGN.md §7). When neither these nor
  /// scan_topics are given and the bag has no LaserScan topic, its PointCloud2 topics.
  std::vector<std::string> cloud_topics;
  /// Put the corrected LaserScan on the original topic and keep the raw one as <topic>_raw.
  bool replace = false;
  std::string compression = "none";  ///< of the output: none, bz2 or lz4
  ros_adapter::DeskewParams params;
  /// Called now and then with the fraction done [0, 1] and scans corrected so far.
  std::function<void(double fraction, std::size_t scans)> progress;
  /// Receives notes for the user (the mount used, statics left out, the first of each kind of failure).
  std::function<void(const std::string&)> inform;
  /// When set and it becomes true (a signal handler), the run stops, the temporary file is removed and
  /// deskewBag throws Interrupted.
  const std::atomic<bool>* interrupted = nullptr;
};

struct BagDeskewSummary {
  std::size_t messages = 0;                ///< messages copied from the input
  std::vector<std::string> chosen_topics;  ///< the topics corrected, scans then clouds
  std::vector<std::string> cloud_topics;   ///< those of them that carry PointCloud2
  /// Per scan topic: the same counters as the node's diagnostics.
  std::map<std::string, ros_adapter::PipelineCounters> counters;
};

/// Thrown when options.interrupted became true.
class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted; no output written") {}
};

/// Reprocesses options.input into options.output: every input message as it was (connection headers
/// included: a latched /tf_static stays latched), plus for each scan topic <topic>_deskewed
/// (LaserScan) and <topic>_deskewed_points (PointCloud2); or, with replace, the corrected scan on
/// <topic> and the raw one on <topic>_raw. Writes a temporary file beside the output and renames it at
/// the end, so no partial output is ever left. Throws std::runtime_error with a message for the user:
/// unreadable or corrupt input, output = input, a scan topic the bag lacks (naming its LaserScan
/// topics), no tf between the frames (naming them), invalid options.
BagDeskewSummary deskewBag(const BagDeskewOptions& options);

/// The topics of `bag` that carry sensor_msgs/LaserScan, sorted.
std::vector<std::string> laserScanTopics(rosbag::Bag& bag);
/// The topics of `bag` that carry messages of `datatype` (e.g. "sensor_msgs/PointCloud2"), sorted.
std::vector<std::string> topicsOfType(rosbag::Bag& bag, const std::string& datatype);

}  // namespace lidar_deskew::bag
