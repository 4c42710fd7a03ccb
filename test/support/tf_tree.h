// The tf trees the tests publish (live and through the pipeline): which frames, which links move.
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <sensor_msgs/LaserScan.h>

#include <string>
#include <vector>

#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::test {

/// Default: odom -> base_link on /tf, base_link -> laser on /tf_static. The laser's true pose is always
/// trajectory(t) composed with the mount, whatever links stand between.
struct TfTree {
  std::string fixed = "odom";
  std::string moving = "base_link";  ///< fixed -> moving on /tf (the trajectory)
  std::string base = "base_link";    ///< the deskew's base_frame: `moving`, or a static child of it
  sim::Pose2 base_offset;            ///< moving -> base on /tf_static, when they differ
  std::string plate;                 ///< when set, the mount is base -> plate -> laser
  sim::Pose2 plate_offset;           ///< base -> plate
  std::string laser = "laser";       ///< the scans' frame; equal to base: the laser is the base

  /// The trees of docs/FAULTS.md by name: default, rep105, plate, base, slash.
  static TfTree named(const std::string& name);
};

/// parent -> child at `stamp`, the planar pose as a transform.
geometry_msgs::TransformStamped stamped(const std::string& parent, const std::string& child,
                                        const ros::Time& stamp, const sim::Pose2& pose);

/// The static links of `tree` that put the laser at `mount` on the moving frame: moving -> base, and
/// base -> (plate ->) laser.
std::vector<geometry_msgs::TransformStamped> staticLinks(const TfTree& tree, const sim::Pose2& mount,
                                                         const ros::Time& stamp);

/// A simulated scan as its driver publishes it, in `frame`.
sensor_msgs::LaserScan scanMessage(const sim::SimulatedScan& simulated, const std::string& frame);

/// A robot driving the simulator's 6 m/s, 5 rad/s arc in the demo room, its laser (UTM-30LX 40 Hz by
/// default) at `mount` on the moving frame, tf as `tree` says; t [s] counts from `epoch`.
struct Drive {
  explicit Drive(const TfTree& tree = TfTree(), const sim::LidarModel& model = sim::LidarModel::utm30lx360());

  ros::Time stampOf(double t) const;
  double secondsOf(const ros::Time& stamp) const;
  /// fixed -> moving at t, on /tf.
  geometry_msgs::TransformStamped motionAt(double t) const;
  /// The tree's static links for the current mount, stamped at t = 0.
  std::vector<geometry_msgs::TransformStamped> statics() const {
    return staticLinks(tree, mount, stampOf(0.0));
  }
  /// The scan whose first beam is at t (noise off), in the tree's laser frame.
  sensor_msgs::LaserScan::Ptr scanAt(double t) const;
  /// Distances [m] to the true walls of points (x, y) in the laser frame at `reference`.
  template <typename Points>
  std::vector<double> distances(const Points& points, const ros::Time& reference) const {
    const sim::Pose2 laser = trajectory.pose(secondsOf(reference)).compose(mount);
    std::vector<double> result;
    for (const auto& point : points)
      result.push_back(world.distanceTo(laser.apply({point.x, point.y})));
    return result;
  }

  TfTree tree;
  sim::World world;
  sim::ArcTrajectory trajectory;
  sim::LidarModel model;
  sim::Pose2 mount{0.25, 0.05, 0.1};  ///< the laser on the moving frame
  core::TimeNs epoch = 1'700'000'000'000'000'000;
};

/// RMS of errors [their unit].
double rms(const std::vector<double>& values);

}  // namespace lidar_deskew::test
