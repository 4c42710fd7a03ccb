// A drive whose turn rate changes every second or two, in the simulator's hall, and what a test of the
// timing's measures records of it (test_timing_fit, test_scan_match).
#pragma once

#include <mrpt/poses/CPose3D.h>

#include <cmath>
#include <vector>

#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::test_support {

/// A drive whose turn rate changes every second or two, in the hall, and a LIDAR on it.
struct TurningDrive {
  sim::LidarModel lidar = sim::LidarModel::ild26tri();
  sim::Pose2 mount{0.1, 0.0, 0.0};
  sim::PiecewiseTrajectory trajectory{sim::Pose2{-4.0, 0.0, 0.0},
                                      {{1.0, 0.0, 0.0, 0.0},
                                       {1.5, 0.0, 0.0, 1.5},
                                       {1.0, 0.5, 0.0, 0.0},
                                       {1.5, 0.3, 0.0, -2.0},
                                       {1.0, 0.0, 0.0, 0.0},
                                       {1.5, 0.0, 0.0, 1.0},
                                       {1.5, 0.5, 0.0, 0.5},
                                       {1.0, 0.0, 0.0, -1.5},
                                       {1.0, 0.0, 0.0, 0.0}}};
  double duration = 10.0;  ///< [s]
};

/// Turns in place at +-2.5 rad/s that start and stop (0.6 s still, 0.8 s turning, each way: 2.8 s a
/// round), `seconds` and up to a round more: the live timing check's drive.
inline std::vector<sim::MotionPiece> startStopTurns(double seconds) {
  std::vector<sim::MotionPiece> pieces;
  for (int k = 0; k < static_cast<int>(std::ceil(seconds / 2.8)); ++k) {
    pieces.push_back({0.6, 0.0, 0.0, 0.0});
    pieces.push_back({0.8, 0.0, 0.0, 2.5});
    pieces.push_back({0.6, 0.0, 0.0, 0.0});
    pieces.push_back({0.8, 0.0, 0.0, -2.5});
  }
  return pieces;
}

/// The drive's scans and its odometry samples, and the laser's mount.
struct TurningRecording {
  std::vector<core::PlanarScan> scans;
  core::PoseSamples motion;
  mrpt::poses::CPose3D mount;
};

}  // namespace lidar_deskew::test_support
