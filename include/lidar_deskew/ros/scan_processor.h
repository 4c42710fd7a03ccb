// From a LaserScan message to the two outputs: the one code path of the live node and deskew_bag.
#pragma once

#include <pcl/point_cloud.h>
#include <sensor_msgs/LaserScan.h>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/point_types.h"

namespace lidar_deskew::ros_adapter {

using DeskewedCloud = pcl::PointCloud<PointXYZITI>;

/// The motion source interpolates across a gap longer than max_tf_gap within the sweep.
class TfGapTooLong : public core::MotionUnavailable {
 public:
  using core::MotionUnavailable::MotionUnavailable;
};

/// Throws TfGapTooLong when `motion` has a gap longer than max_tf_gap [s] (0 = never) in [first, last].
void checkTfGaps(double max_tf_gap, const core::MotionSource& motion, core::TimeNs first, core::TimeNs last);

/// A scan checked and timed, ready to be corrected once its motion is known.
struct PreparedScan {
  sensor_msgs::LaserScan::ConstPtr message;
  core::PlanarScan scan;
  core::BeamTiming timing;

  core::TimeNs earliest() const { return timing.earliestBeamTime(); }
  core::TimeNs latest() const { return timing.latestBeamTime(); }
  /// How the beams were timed when not by time_increment, for the log; nullptr when by it.
  const char* timingFallback() const;
  /// For clouds, which field timed them; a scan's timing is its message's (timingFallback() otherwise).
  std::string timingFound() const { return {}; }
};

/// The two outputs of one scan, in the scan's frame, stamped at the reference time.
struct DeskewedOutputs {
  sensor_msgs::LaserScan::ConstPtr scan;   ///< re-binned on the input grid
  boost::shared_ptr<DeskewedCloud> cloud;  ///< x y z intensity t index
};

/// Corrects scans with the core; keeps its caches, so use one per input stream. Not thread-safe.
class ScanProcessor {
 public:
  using Message = sensor_msgs::LaserScan;
  static constexpr const char* kNoun = "scan";  ///< what logs and diagnostics call one message
  using Prepared = PreparedScan;
  using Outputs = DeskewedOutputs;

  /// Throws core::InvalidInput for invalid parameters.
  explicit ScanProcessor(const DeskewParams& params);

  /// Checks a message and resolves its beam times. Throws core::InvalidInput naming the bad field
  /// (an empty frame_id, or a stamp that puts the sweep outside ROS time, included).
  PreparedScan prepare(const sensor_msgs::LaserScan::ConstPtr& message) const;

  /// Corrects with `motion` (base in the fixed frame) and `mount` (base -> scan frame), re-bins, and
  /// builds both messages. Throws core::MotionUnavailable when the motion does not cover the sweep, and
  /// TfGapTooLong when it has a gap longer than max_tf_gap there.
  DeskewedOutputs correct(const PreparedScan& prepared, const mrpt::poses::CPose3D& mount,
                          const core::MotionSource& motion);

  /// The uncorrected outputs (on_tf_failure: pass_through): the input scan itself, and its plain
  /// polar projection stamped at the reference time (its t field is relative to that).
  DeskewedOutputs passThrough(const PreparedScan& prepared);

 private:
  DeskewParams params_;
  core::ScanDeskewer deskewer_;
  core::ScanRebinner rebinner_;
  core::DeskewedScan corrected_;
  core::RebinnedScan rebinned_;
};

}  // namespace lidar_deskew::ros_adapter
