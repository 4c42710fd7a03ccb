// The live deskew: LaserScan in, corrected LaserScan and PCL cloud out, motion from tf2. One class
// behind both the nodelet and the plain node (DESIGN §2-§5).
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <pcl/point_cloud.h>
#include <pcl_ros/point_cloud.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2/buffer_core.h>
#include <tf2_msgs/TFMessage.h>

#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/ros/params.h"
#include "lidar_deskew/ros/point_types.h"
#include "lidar_deskew/ros/scan_processor.h"
#include "lidar_deskew/ros/tf_motion.h"

namespace lidar_deskew::ros_adapter {

/// Subscribes to `scan` (remappable) while anyone subscribes to an output; publishes `scan_deskewed`
/// (sensor_msgs/LaserScan on the input's grid) and `scan_deskewed_points` (PCL cloud of PointXYZITI),
/// both in the scan's frame, stamped at the reference time. A scan waits, without blocking any
/// callback, until tf covers its last beam, and is processed from the tf callback that brings it.
/// Thread-safe: callbacks may come from several threads.
class LaserScanDeskewNode {
 public:
  /// Why scans were not corrected.
  struct Counters {
    std::uint64_t received = 0;
    std::uint64_t published = 0;        ///< corrected scans published
    std::uint64_t passed_through = 0;   ///< published uncorrected (on_tf_failure: pass_through)
    std::uint64_t extrapolated = 0;     ///< corrected with tf extrapolated up to max_extrapolation
    std::uint64_t dropped_invalid = 0;  ///< malformed scans
    std::uint64_t dropped_tf = 0;       ///< tf did not cover the sweep within tf_timeout
    std::uint64_t dropped_mount = 0;    ///< no transform base_frame -> scan frame
    std::uint64_t dropped_queue = 0;    ///< more than queue_size scans were waiting
    std::uint64_t time_fallbacks = 0;   ///< scans timed by scan_time or scan_period (time_increment 0)
    std::uint64_t tf_gaps = 0;          ///< refused: tf has a gap longer than max_tf_gap in the sweep
    std::uint64_t mount_changes = 0;    ///< the mount base_frame -> scan frame changed at run time
    std::uint64_t time_jumps = 0;       ///< time went backwards: tf cache and queue cleared
    double tf_wait_total = 0.0;         ///< [s] arrival to "tf covers the last beam", summed
    double tf_wait_max = 0.0;           ///< [s]
    double processing_total = 0.0;      ///< [s] correction + re-binning + publishing, summed
    double processing_max = 0.0;        ///< [s]
  };

  /// Reads and validates the parameters (throws core::InvalidInput naming the bad one: nothing is
  /// advertised then), advertises the outputs and listens to /tf and /tf_static. `name` prefixes log
  /// lines and names the diagnostics.
  LaserScanDeskewNode(ros::NodeHandle nh, ros::NodeHandle private_nh, std::string name);
  ~LaserScanDeskewNode();

  LaserScanDeskewNode(const LaserScanDeskewNode&) = delete;
  LaserScanDeskewNode& operator=(const LaserScanDeskewNode&) = delete;

  const DeskewParams& params() const { return params_; }
  Counters counters() const;

  /// [s] 99th percentile of the latency from the callback in which tf covered a scan's last beam (or
  /// the scan arrived already covered) to its outputs being published, over the last 1000 scans.
  double latencyP99() const;

  /// Address of the last cloud any instance in this process published (tests prove zero-copy with it).
  static const void* lastPublishedCloud();

 private:
  struct Pending {
    PreparedScan prepared;
    ros::WallTime arrival;
  };

  void connectCallback();
  void scanCallback(const sensor_msgs::LaserScan::ConstPtr& message);
  void tfCallback(const tf2_msgs::TFMessage::ConstPtr& message, bool is_static);
  void timerCallback(const ros::WallTimerEvent& event);

  // All below run with mutex_ held.
  void processReady(ros::WallTime trigger);
  bool sweepCovered(const Pending& pending, bool& extrapolate) const;
  void correctAndPublish(const Pending& pending, bool extrapolate, ros::WallTime trigger);
  void failOnTf(const Pending& pending, const std::string& reason);
  bool mountKnown(const std::string& frame) const;
  bool lookupMount(const std::string& frame, mrpt::poses::CPose3D& mount);
  void resetForTimeJump();
  core::TimeNs newestChainTime() const;
  void produceDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status);
  double latencyP99Locked() const;

  ros::NodeHandle nh_;
  ros::NodeHandle private_nh_;
  std::string name_;
  DeskewParams params_;

  mutable std::mutex mutex_;
  std::mutex connect_mutex_;
  bool shutting_down_ = false;  // guarded by connect_mutex_
  tf2::BufferCore buffer_;
  TfMotionSource motion_;
  ScanProcessor processor_;
  std::deque<Pending> pending_;
  std::map<std::string, mrpt::poses::CPose3D> mounts_;  // the last mount of each scan frame
  core::TimeNs newest_base_stamp_ = 0;                  // [ns] newest dynamic transform to base_frame
  Counters counters_;
  std::vector<double> latencies_;  // [s] ring of the last kLatencies
  std::size_t next_latency_ = 0;
  Counters counters_at_last_diagnostics_;
  ros::WallTime last_diagnostics_;
  ros::WallTime last_tick_;      // the timer's last run
  ros::WallTime running_since_;  // the end of the last stall of this process

  ros::Publisher scan_publisher_;
  ros::Publisher cloud_publisher_;
  ros::Subscriber scan_subscriber_;
  ros::Subscriber tf_subscriber_;
  ros::Subscriber tf_static_subscriber_;
  ros::WallTimer timer_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
};

}  // namespace lidar_deskew::ros_adapter
