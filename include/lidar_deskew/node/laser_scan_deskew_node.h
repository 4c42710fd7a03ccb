// The live deskew: LaserScan in, corrected LaserScan and PCL cloud out; or PointCloud2 in, corrected
// PointCloud2 out; motion from tf2. One class template behind the nodelets and the plain nodes; the
// work is ros_adapter::SweepPipeline's, shared with deskew_bag. This class owns the ROS side:
// subscriptions, publishing, waiting on the wall clock, diagnostics (docs/DESIGN.md).
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <string>
#include <vector>

#include "lidar_deskew/core/scan_match.h"
#include "lidar_deskew/core/timing_fit.h"
#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/scan_pipeline.h"

namespace lidar_deskew::node {

/// Subscribes to its input (remappable: `scan` for ScanProcessor, `points` for CloudProcessor) while
/// anyone subscribes to an output; publishes, named after the input as remapped, for scans
/// `<scan>_deskewed` (sensor_msgs/LaserScan on the input's grid) and `<scan>_deskewed_points` (PCL cloud
/// of PointXYZITI), for clouds `<points>_deskewed` (PointCloud2, the input's layout), all in the input's
/// frame, stamped at the reference time. A scan waits, without blocking any
/// callback, until tf covers its last beam, and is processed from the tf callback that brings it.
/// The reconfigurable parameters its input reads (DeskewParams::reconfigurableNames(Input)) may change
/// while it runs, through dynamic_reconfigure (cfg/DeskewScan.cfg, cfg/DeskewCloud.cfg); a change it
/// cannot take is refused, logged, and the values in force are sent back to the client. Scans: a live check
/// that the timing fits (core::TimingCheck) runs on corrected scans while its CPU time stays within 5 % of
/// the node's callbacks', and reports on /diagnostics ("<name>: timing") once the robot has turned enough.
/// Thread-safe: callbacks may come from several threads.
template <class Processor>
class DeskewNode {
 public:
  using Message = typename Processor::Message;
  using Pipeline = ros_adapter::SweepPipeline<Processor>;

  /// The pipeline's counters and the node's timing.
  struct Counters : ros_adapter::PipelineCounters {
    double tf_wait_total = 0.0;     ///< [s] arrival to "tf covers the last beam", summed
    double tf_wait_max = 0.0;       ///< [s]
    double processing_total = 0.0;  ///< [s] correction + re-binning + publishing, summed
    double processing_max = 0.0;    ///< [s]
  };

  /// Reads and validates the parameters (throws core::InvalidInput naming the bad one: nothing is
  /// advertised then), advertises the outputs and listens to /tf and /tf_static. `name` prefixes log
  /// lines and names the diagnostics.
  DeskewNode(ros::NodeHandle nh, ros::NodeHandle private_nh, std::string name);
  ~DeskewNode();

  DeskewNode(const DeskewNode&) = delete;
  DeskewNode& operator=(const DeskewNode&) = delete;

  /// The parameters in force (dynamic_reconfigure changes some while running).
  ros_adapter::DeskewParams params() const;
  Counters counters() const;

  /// [s] 99th percentile of the latency from the callback in which tf covered a scan's last beam (or
  /// the scan arrived already covered) to its outputs being published, over the last 1000 scans.
  double latencyP99() const;

  /// Address of the last cloud any instance in this process published (tests prove zero-copy with it).
  static const void* lastPublishedCloud();

 private:
  void connectCallback();
  void inputCallback(const typename Message::ConstPtr& message);
  void advertiseOutputs(const std::string& input, const ros::SubscriberStatusCallback& connect);
  void tfCallback(const tf2_msgs::TFMessage::ConstPtr& message, bool is_static);
  void timerCallback(const ros::WallTimerEvent& event);
  struct Reconfigure;  // the dynamic_reconfigure server, of DeskewScanConfig or DeskewCloudConfig

  // All below run with mutex_ held.
  void publish(const typename Pipeline::Result& result);
  void report(ros_adapter::PipelineEvent event, const std::string& text);
  void produceDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status);
  void produceTimingDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status);
  void produceRotationDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status);
  using Produce = void (DeskewNode::*)(diagnostic_updater::DiagnosticStatusWrapper&);
  /// Puts the status `name` on /diagnostics (produced by `produce`) when `known` turns true, takes it off
  /// when it turns false; `reported` says whether it is on. The diagnostics timer's alone, outside mutex_.
  void showStatus(const std::optional<bool>& known, bool& reported, const char* name, Produce produce);
  /// Whether one more timing check, costing three times the costliest of late, stays within 5 % of the
  /// callbacks' CPU.
  bool timingCheckAffordable() const;
  /// Runs `check` (the timing check's work), adding its CPU time to check_cpu_ and keeping the costliest
  /// check of late.
  template <class Check>
  void timeCheck(Check&& check);
  /// Offers every sweep to the timing check (a shape partner; its copy counts as check CPU), feeds it a
  /// corrected sweep when its CPU budget allows, and the rotation monitor (scans only).
  void checkTiming(const typename Processor::Prepared& prepared, const mrpt::poses::CPose3D& mount);
  double latencyP99Locked() const;
  Counters countersLocked() const;  ///< the pipeline's counters with the node's timing

  ros::NodeHandle nh_;
  ros::NodeHandle private_nh_;
  std::string name_;
  ros_adapter::DeskewParams params_;  // guarded by mutex_ (reconfigured while running)
  const int input_queue_size_;        // params_.input_queue_size, which cannot change

  mutable std::mutex mutex_;
  std::mutex connect_mutex_;
  bool shutting_down_ = false;  // guarded by connect_mutex_
  Pipeline pipeline_;
  Counters timing_;        // the timing fields only; the rest is the pipeline's
  ros::WallTime trigger_;  // the callback now serving scans
  std::map<ros_adapter::PipelineEvent, ros::WallTime> last_report_;  // for throttling
  std::string last_drop_;          // why the newest dropped (or passed through) sweep was, for /diagnostics
  std::vector<double> latencies_;  // [s] ring of the last kLatencies
  std::size_t next_latency_ = 0;
  Counters counters_at_last_diagnostics_;
  ros::WallTime last_diagnostics_;
  ros::WallTime last_tick_;      // the timer's last run
  ros::WallTime running_since_;  // the end of the last stall of this process

  std::vector<ros::Publisher> publishers_;  // scans: the scan and its cloud; clouds: the cloud
  ros::Subscriber input_subscriber_;
  ros::Subscriber tf_subscriber_;
  ros::Subscriber tf_static_subscriber_;
  ros::WallTimer timer_;
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  // The live timing check (scans only; guarded by mutex_).
  std::unique_ptr<core::TimingCheck> timing_check_;
  double callbacks_cpu_ = 0.0;      // [s] thread CPU time in the node's callbacks, the check's included
  double check_cpu_ = 0.0;          // [s] of it in the timing check
  double largest_check_cpu_ = 0.0;  // [s] the costliest check of late (timeCheck)
  bool timing_reported_ = false;    // the timing status is on /diagnostics (the timer's alone)
  // The live check that tf's rotation fits the scans (scans only; guarded by mutex_): one match of two
  // consecutive raw scans every 2 s.
  std::unique_ptr<core::RotationMonitor> rotation_monitor_;
  bool rotation_reported_ = false;  // its status is on /diagnostics (the timer's alone)
  std::unique_ptr<Reconfigure> reconfigure_;
};

using LaserScanDeskewNode = DeskewNode<ros_adapter::ScanProcessor>;
using PointCloudDeskewNode = DeskewNode<ros_adapter::CloudProcessor>;
extern template class DeskewNode<ros_adapter::ScanProcessor>;
extern template class DeskewNode<ros_adapter::CloudProcessor>;

}  // namespace lidar_deskew::node
