// Reading a bag's tf for the correction: shared by deskew_bag, deskew_metrics and the consistency measure.
#pragma once

#include <rosbag/bag.h>
#include <tf2/buffer_core.h>

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "lidar_deskew/ros/params.h"
#include "lidar_deskew/ros/tf_motion.h"

namespace lidar_deskew::ros_adapter {

/// Where the laser mount (base_frame -> scan frame) is taken from when the bag has it on both
/// /tf and /tf_static.
enum class MountSource { kTfStatic, kTf };

/// All of a bag's tf in one buffer, the mount chosen between /tf and /tf_static, and the motion source.
struct BagTf {
  std::unique_ptr<tf2::BufferCore> buffer;
  std::unique_ptr<TfMotionSource> motion;              ///< fixed_frame -> base_frame, over `buffer`
  std::map<std::string, mrpt::poses::CPose3D> mounts;  ///< scan frame -> pose of it on the base
  std::string report;                                  ///< which mounts were used, conflicts, ignored links
};

/// Opens a bag for reading; throws std::runtime_error naming the file when it cannot.
rosbag::Bag openForReading(const std::string& path);

/// The frame of the first LaserScan on each topic.
std::set<std::string> scanFrames(rosbag::Bag& bag, const std::vector<std::string>& topics);

/// Loads every /tf (dynamic) and /tf_static (static) transform of the bag into one buffer spanning the
/// whole bag, takes the mount of each scan frame from `mount_from` when both carry it (reporting a
/// disagreement), and ignores /tf_static parents of frames that move on /tf (tf2 would answer one pose
/// for all times). Throws std::runtime_error naming the frames when there is no mount or no tf from
/// fixed_frame to base_frame.
BagTf loadTf(rosbag::Bag& bag, const std::string& bag_path, const std::set<std::string>& scan_frames,
             const DeskewParams& params, MountSource mount_from);

}  // namespace lidar_deskew::ros_adapter
