// The odometry classes the twist fit is held against tf's line with, planar (test_paper_cases) and 3D
// (test_cloud_odometry): odometry samples as robots produce them (sim::OdometryTiming).
#pragma once

#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::test {

/// Stamps off by up to `jitter` [s], an irregular rate in [rate_min, rate_max] [Hz] (0, 0: the grid),
/// encoder ticks of `tick` [m] on a 0.3 m wheel base (0: none).
inline sim::OdometryTiming odometryTiming(double jitter, double rate_min, double rate_max, double tick) {
  sim::OdometryTiming timing;
  timing.jitter = jitter;
  timing.rate_min = rate_min;
  timing.rate_max = rate_max;
  timing.tick = tick;
  timing.wheel_base = tick > 0.0 ? 0.3 : 0.0;
  return timing;
}

}  // namespace lidar_deskew::test
