// Test support for the live deskew: plays the simulator's trajectory through /tf (odom -> base_link at
// 50 Hz, base_link -> laser static) and publishes its scans, as a robot would; collects the outputs.
#pragma once

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "lidar_deskew/sim/sim.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {

class LiveRig {
 public:
  /// Advertises /tf, /tf_static (latched) and `scan` in namespace `ns`; t = 0 of the simulation is
  /// ros::Time::now(). With `ns`, only the diagnostics of a deskew named in it are read.
  explicit LiveRig(const sim::LidarModel& lidar = sim::LidarModel::utm30lx360(), const std::string& ns = "");
  /// The same with the base driving `pieces` (sim::PiecewiseTrajectory) from the usual start instead of
  /// the arc at 6 m/s and 5 rad/s.
  LiveRig(const sim::LidarModel& lidar, const std::string& ns, std::vector<sim::MotionPiece> pieces);

  /// Publishes `tree` from now on (call before connect()).
  void useTree(const TfTree& tree) { tree_ = tree; }

  /// Publishes odometry that reports `yaw_scale` x the true rotation (sim::NoisyOdometry without noise)
  /// on /tf instead of the truth, over t in [-2, `until`] s; the scans stay true.
  void useOdometryYawScale(double yaw_scale, double until = 300.0);

  /// Takes t = 0 from `other`, so that one rig's tf serves both rigs' scans.
  void shareClockWith(const LiveRig& other) { epoch_ = other.epoch_; }
  /// Keeps at most the newest `count` outputs of each kind (long runs).
  void limitHistory(std::size_t count) { history_ = count; }

  /// Subscribes to scan_deskewed, scan_deskewed_points (PointCloud2) and /diagnostics.
  void subscribeOutputs();
  /// subscribeOutputs(), then waits until the deskew subscribes to `scan` (lazy subscription) and the
  /// outputs are connected, and publishes the mount. False when that did not happen within 5 s.
  bool connect();
  void unsubscribeOutputs();

  /// Waits until the deskew is connected to /tf and /tf_static, then publishes base_link -> laser.
  void publishMount();
  /// Publishes a new mount on /tf_static (as a recalibration would), through the tree's static links,
  /// stamped at t [s] (default: t = 0, so it serves every scan corrected from now on); scans ending at
  /// or after that stamp use it.
  void setMount(const sim::Pose2& new_mount, double t = 0.0);
  /// Publishes parent -> child on /tf_static, stamped at t = 0 (only this transform in the message).
  void publishStatic(const std::string& parent, const std::string& child, const sim::Pose2& pose);
  /// odom -> base_link samples every 20 ms from the last published one up to t [s] (inclusive).
  void publishTfUntil(double t);
  /// Leaves out the samples up to t [s]: the next publishTfUntil() starts after t (a tf gap).
  void skipTfUntil(double t) { tf_until_ = t; }
  /// The scan whose first beam is at t [s] (noise off), as the driver publishes it.
  sim::SimulatedScan publishScan(double t, const std::function<void(sensor_msgs::LaserScan&)>& modify = {});

  /// Spins until `done` or `timeout` [s]; returns done().
  bool waitFor(const std::function<bool()>& done, double timeout);
  /// Spins (handles this process's callbacks) for `seconds`.
  void spinFor(double seconds) {
    waitFor([] { return false; }, seconds);
  }
  /// The outputs stamped `stamp` (within `tolerance` [s]), when both arrived within `timeout` [s].
  bool waitForOutputs(const ros::Time& stamp, double timeout, sensor_msgs::LaserScan::ConstPtr& scan,
                      sensor_msgs::PointCloud2::ConstPtr& cloud, double tolerance = 0.0);
  /// How many corrected scans arrived stamped within [from, to].
  std::size_t outputCount(const ros::Time& from, const ros::Time& to) const;
  /// The newest value of a diagnostics key of the deskew status (empty when none arrived yet).
  std::string diagnostic(const std::string& key) const;
  double diagnosticNumber(const std::string& key) const;
  /// The newest level and message of the status whose name ends with `suffix` (e.g. ": timing");
  /// false when none arrived.
  bool status(const std::string& suffix, int& level, std::string& message) const;
  /// The names of the deskew's statuses that arrived on /diagnostics so far.
  std::vector<std::string> statusNames() const;
  /// How many statuses of the deskew arrived on /diagnostics so far.
  std::size_t diagnosticsReceived() const { return diagnostics_received_; }

  ros::Time stampOf(double t) const;
  double secondsOf(const ros::Time& stamp) const;

  const sim::World world;
  const sim::PiecewiseTrajectory trajectory;
  sim::Pose2 mount;  ///< base_link -> laser, as last published
  const sim::LidarModel model;
  ros::Publisher scan_publisher;

 private:
  ros::NodeHandle nh_;
  std::string diagnostics_name_;  // a status is read when its name holds this
  std::size_t history_ = static_cast<std::size_t>(-1);
  ros::Time epoch_;
  double tf_until_ = -0.1;
  TfTree tree_;
  std::unique_ptr<sim::NoisyOdometry> odometry_;  // what /tf says, when not the truth
  ros::Publisher tf_publisher_, tf_static_publisher_;
  ros::Subscriber scan_subscriber_, cloud_subscriber_, diagnostics_subscriber_;
  std::deque<sensor_msgs::LaserScan::ConstPtr> scans_;
  std::deque<sensor_msgs::PointCloud2::ConstPtr> clouds_;
  std::map<std::string, std::string> diagnostics_;
  std::map<std::string, std::pair<int, std::string>> statuses_;  // by name: level, message
  std::size_t diagnostics_received_ = 0;
};

/// The test node's private boolean parameter `name` (a rostest <param>); false when not set.
bool testFlag(const std::string& name);

/// Distances [m] of the corrected cloud's points, and of the corrected scan's beam endpoints, to the
/// true walls, placed with the laser's true pose at the output stamp (the reference time).
std::vector<double> cloudDistances(const LiveRig& rig, const sensor_msgs::PointCloud2& cloud);
/// The same with the laser at `mount` on the base (not the rig's current one).
std::vector<double> cloudDistances(const LiveRig& rig, const sensor_msgs::PointCloud2& cloud,
                                   const sim::Pose2& mount);
std::vector<double> scanDistances(const LiveRig& rig, const sensor_msgs::LaserScan& scan);
/// Distances [m] of the raw scan's beam endpoints to the true walls, drawn from the laser's true pose
/// at the scan's start `start` [s] as if the robot stood still (what the correction removes).
std::vector<double> rawDistances(const LiveRig& rig, const sim::SimulatedScan& input, double start);

}  // namespace lidar_deskew::test
