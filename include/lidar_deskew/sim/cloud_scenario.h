// Named experiments for multi-line LIDARs (sim3d.h) and the ground-truth file of a simulated cloud bag.
// ROS-free.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidar_deskew/core/types.h"
#include "lidar_deskew/sim/scenario.h"
#include "lidar_deskew/sim/sim3d.h"

namespace lidar_deskew::sim {

/// One experiment: a spinning LIDAR on a robot moving through World3::hall().
struct CloudScenario {
  std::string name;  ///< "<sensor>/<speed>/<motion>", e.g. "VLP16/rough/arc"
  SpinningLidarModel lidar;
  std::string speed;   ///< "static", "normal", "high", "varying" or "rough"
  std::string motion;  ///< "still", "arc", "turn", "varying" or "smooth"
  Pose3 mount;         ///< sensor on the base
  Pose2 start;         ///< base pose in the world at t = 0 (planar part)
  std::vector<MotionPiece> pieces;
  std::optional<RoughGround> rough;  ///< set: z, roll and pitch oscillate; unset: flat ground
  double duration = 1.0;             ///< [s] sweeps start at 0, 1/rate, ... while below duration

  /// The true base motion: planar pieces, on rough ground when `rough` is set.
  std::shared_ptr<const Trajectory3> trajectory() const;
  /// Start time [s] of every sweep.
  std::vector<double> sweepStartTimes() const;
};

/// For VLP16 and OS1-64 each, mirroring the planar suite: "static/still" (standing), "normal/arc"
/// (1.5 m/s, 2 rad/s), "normal/turn" (2 rad/s in place), "high/arc" (6 m/s, 5 rad/s), "high/turn"
/// (5 rad/s in place), "varying/varying" (speed 1-5 m/s and turn +-4 rad/s changing every 40 ms, as
/// the planar ILD26TRI/varying/varying) and "rough/arc" (the normal arc on rough ground, RoughGround's
/// defaults: z, roll and pitch move). Mount: x 0.1, z 0.5 m, roll 1 deg, pitch 2 deg; at high and
/// varying speed x 0.25, y 0.05, z 0.6 m, roll 1 deg, pitch 2 deg, yaw 0.1 rad (off the rotation
/// centre, as the planar high-speed cases). Start (-10, 0.5, 0) as the planar suite; 1 s, 10 sweeps.
/// 14 scenarios.
std::vector<CloudScenario> cloudScenarios();
/// Motion whose twist changes all the time, between tf samples too, as the planar smoothScenarios()
/// (sim::smoothUnicyclePieces): the speed follows a cosine of period 2 s from its peak through zero into
/// reverse, the turn rate one of period 1.3 s. For VLP16 and OS1-64 each: "normal/smooth" (peaks
/// 1.5 m/s and 2 rad/s), "high/smooth" (6 m/s and 5 rad/s) and "rough/smooth" (the normal drive on
/// RoughGround's defaults). Mounts as cloudScenarios() (high: off the rotation centre); start
/// (-10, -1.5, 0) as the planar smooth drives, 1.3 s (one period of the turn rate), 13 sweeps.
/// 6 scenarios, not part of cloudScenarios() (docs/RESULTS_CLOUDS.md has them in their own table).
std::vector<CloudScenario> cloudSmoothScenarios();
/// The scenario of that name, of cloudScenarios() or cloudSmoothScenarios(); throws
/// std::invalid_argument listing the names otherwise.
CloudScenario findCloudScenario(const std::string& name);

/// What an evaluator needs to know about a simulated cloud bag: the world, the true motion, the mount,
/// the sensor and when each sweep started. The motion is kept as its parameters, so poses are exact.
struct CloudTruth {
  std::string scenario;
  std::string world = "hall";  ///< World3::byName
  std::string sensor;          ///< SpinningLidarModel::byName
  std::string convention;      ///< the cloud layout written (cloud_bag.h), for the record
  core::TimeNs epoch = 0;      ///< [ns] bag time of t = 0
  double range_sigma = 0.0;    ///< [m] range noise used (0 = off)
  Pose3 mount;
  Pose2 start;
  std::vector<MotionPiece> pieces;
  std::optional<RoughGround> rough;
  std::vector<double> sweep_start_times;  ///< [s] column 0's time of each sweep, from the epoch
  /// The odometry on /tf (CloudBagOptions; the motion above stays the true one): as Truth's fields.
  double odom_noise = 0.0;
  unsigned odom_noise_seed = 0;
  double odom_yaw_scale = 1.0;
  OdometryTiming odom_timing;

  std::shared_ptr<const Trajectory3> trajectory() const;
  /// True sensor pose in the world at bag time `time` [ns] (base(t) (+) mount).
  Pose3 sensorPose(core::TimeNs time) const;
  /// True sensor pose at `t` [s] on the simulation clock.
  Pose3 sensorPoseAt(double t) const;
};

/// Writes / reads the cloud truth file (a line-based text format, full double precision; the mount
/// as position and the 9 entries of its rotation matrix; the odometry lines as the planar truth's
/// (writeTruth), only when the odometry is not the truth). read throws std::runtime_error naming the
/// file and line on malformed input.
void writeCloudTruth(const CloudTruth& truth, const std::string& path);
CloudTruth readCloudTruth(const std::string& path);

}  // namespace lidar_deskew::sim
