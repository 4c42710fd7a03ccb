// The paper's simulation experiments as named scenarios, and the ground-truth file that goes with a
// simulated bag. ROS-free.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::sim {

/// One experiment: a LIDAR on a robot moving through the hall.
struct Scenario {
  std::string name;  ///< e.g. "UTM-30LX/high/arc"
  LidarModel lidar;
  std::string speed;   ///< "normal" (1.5 m/s, 2 rad/s), "high" (6 m/s, 5 rad/s) or "varying"
  std::string motion;  ///< "translation", "rotation", "arc" or "varying"
  Pose2 mount;         ///< laser on the base
  Pose2 start;         ///< base pose in the world at t = 0
  std::vector<MotionPiece> pieces;
  double duration = 1.0;  ///< [s] scans start at 0, 1/rate, ... while below duration

  PiecewiseTrajectory trajectory() const { return PiecewiseTrajectory(start, pieces); }
};

/// The paper's table: UTM-30LX 1440/360 deg/40 Hz, ILD26TRI 360/360 deg/8 Hz, UTM-30LX 1080/270 deg/
/// 40 Hz; translation, rotation and both; normal speed (1.5 m/s, 2 rad/s, laser on the rotation centre)
/// and high speed (6 m/s, 5 rad/s, laser 0.25 m ahead, 0.05 m left, turned 0.1 rad). Plus "varying":
/// the ILD26TRI with speed and turn rate changing inside each scan. 19 scenarios.
std::vector<Scenario> paperScenarios();
/// The scenario of that name; throws std::invalid_argument listing the names otherwise.
Scenario findScenario(const std::string& name);
/// The same experiment with the sensor turning clockwise (negative angle increment); name + "/clockwise".
Scenario clockwiseVariant(Scenario scenario);

/// What the metrics need to know about a simulated bag: the world, the true motion, the mount.
struct Truth {
  std::string scenario;
  core::TimeNs epoch = 0;    ///< [ns] bag time of t = 0
  double range_sigma = 0.0;  ///< [m] range noise used (0 = off)
  Pose2 mount;
  Pose2 start;
  std::vector<MotionPiece> pieces;
  World world;

  PiecewiseTrajectory trajectory() const { return PiecewiseTrajectory(start, pieces); }
  /// True laser pose in the world at bag time `time` [ns].
  Pose2 laserPose(core::TimeNs time) const;
};

/// Writes / reads the ground-truth file (a small line-based text format, full double precision).
/// read throws std::runtime_error naming the file and line on malformed input.
void writeTruth(const Truth& truth, const std::string& path);
Truth readTruth(const std::string& path);

}  // namespace lidar_deskew::sim
