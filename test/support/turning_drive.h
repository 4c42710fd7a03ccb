// A drive whose turn rate changes every second or two, in the simulator's hall, and what a test of the
// timing's measures records of it (test_timing_fit, test_scan_match).
#pragma once

#include <mrpt/poses/CPose3D.h>

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

/// The drive's scans and its odometry samples, and the laser's mount.
struct TurningRecording {
  std::vector<core::PlanarScan> scans;
  core::PoseSamples motion;
  mrpt::poses::CPose3D mount;
};

}  // namespace lidar_deskew::test_support
