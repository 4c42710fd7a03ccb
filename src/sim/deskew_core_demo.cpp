// deskew_core_demo: the core correcting simulated scans of the paper's sensors on a fast arc, printing
// how far raw and corrected points lie from the true walls.
//
// Usage: deskew_core_demo [--noise[=true|false]] [--pose-rate HZ] [--seed N]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/sim/sim.h"

namespace {

using namespace lidar_deskew;

constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;

mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose) {
  return mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0);
}

void usage(const char* program) {
  std::fprintf(stderr, "usage: %s [--noise[=true|false]] [--pose-rate HZ] [--seed N]\n", program);
}

}  // namespace

int main(int argc, char** argv) {
  bool noise = false;
  double pose_rate = 50.0;  // [Hz] like odom -> base_link on tf
  unsigned seed = 1;
  for (int a = 1; a < argc; ++a) {
    if (!std::strcmp(argv[a], "--noise") || !std::strcmp(argv[a], "--noise=true")) {
      noise = true;
    } else if (!std::strcmp(argv[a], "--noise=false")) {
      noise = false;
    } else if (!std::strcmp(argv[a], "--pose-rate") && a + 1 < argc) {
      pose_rate = std::atof(argv[++a]);
    } else if (!std::strcmp(argv[a], "--seed") && a + 1 < argc) {
      seed = static_cast<unsigned>(std::atoi(argv[++a]));
    } else {
      usage(argv[0]);
      return 2;
    }
  }
  if (!(pose_rate > 0.0)) {
    std::fprintf(stderr, "--pose-rate must be > 0 Hz\n");
    return 2;
  }

  const sim::World world = sim::World::demoRoom();
  const sim::Pose2 mount{0.25, 0.05, 0.1};  // laser ahead of the rotation centre, as in the paper
  std::mt19937 rng(seed);
  struct Motion {
    const char* name;
    double speed, yaw_rate;
  };
  const Motion motions[] = {{"translation", 6.0, 0.0}, {"rotation", 0.0, 5.0}, {"arc", 6.0, 5.0}};

  std::printf(
      "lidar_deskew core demo: one simulated scan per row, laser mounted at (0.25 m, 0.05 m, 0.1 rad),\n");
  std::printf("poses sampled at %.0f Hz, knots every 5 ms, reference = scan start, noise %s.\n", pose_rate,
              noise ? "on" : "off");
  std::printf("Distance of each point to the true walls [mm]; 'scan' = re-binned LaserScan endpoints.\n\n");
  std::printf("%-13s %-12s %7s | %9s %9s | %9s %9s | %9s %9s\n", "sensor", "motion", "points", "raw RMS",
              "raw max", "corr RMS", "corr max", "scan RMS", "scan max");
  for (const sim::LidarModel& model :
       {sim::LidarModel::utm30lx360(), sim::LidarModel::ild26tri(), sim::LidarModel::utm30lx270()}) {
    for (const Motion& motion : motions) {
      const sim::ArcTrajectory trajectory({-2.0, -1.0, 0.3}, motion.speed, motion.yaw_rate);
      const sim::SimulatedScan simulated =
          sim::simulateScan(world, trajectory, mount, model, kEpoch, 0.0, noise ? &rng : nullptr);
      core::PoseSamples poses;
      for (double t = -0.1; t < 0.5; t += 1.0 / pose_rate) {
        poses.add(kEpoch + core::secondsToNs(t), toMrpt(trajectory.pose(t)));
      }
      core::ScanDeskewer deskewer;
      core::DeskewedScan corrected;
      deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), toMrpt(mount), poses,
                      corrected);
      core::ScanRebinner rebinner;
      core::RebinnedScan rebinned;
      const core::AngleGrid grid{simulated.scan.angle_min, simulated.scan.angle_increment,
                                 simulated.scan.ranges.size()};
      rebinner.rebin(corrected, grid, core::noReturnValue(simulated.scan), rebinned);

      // Everything is drawn in the laser frame at the reference time; truth puts it in the world.
      const sim::Pose2 laser =
          trajectory.pose(core::nsToSeconds(corrected.reference_time - kEpoch)).compose(mount);
      std::vector<double> raw_errors, corrected_errors, scan_errors;
      for (const core::DeskewedPoint& point : corrected.points) {
        const double angle =
            simulated.scan.angle_min + point.beam_index * static_cast<double>(simulated.scan.angle_increment);
        const double range = simulated.scan.ranges[point.beam_index];
        raw_errors.push_back(
            world.distanceTo(laser.apply({range * std::cos(angle), range * std::sin(angle)})));
        corrected_errors.push_back(world.distanceTo(laser.apply(point.position.head<2>())));
      }
      for (std::size_t b = 0; b < rebinned.ranges.size(); ++b) {
        if (!std::isfinite(rebinned.ranges[b]))
          continue;
        const double angle = grid.angle_min + b * static_cast<double>(grid.angle_increment);
        const double range = rebinned.ranges[b];
        scan_errors.push_back(
            world.distanceTo(laser.apply({range * std::cos(angle), range * std::sin(angle)})));
      }
      const sim::ErrorStats raw = sim::errorStats(raw_errors).scaled(1e3);
      const sim::ErrorStats fixed = sim::errorStats(corrected_errors).scaled(1e3);
      const sim::ErrorStats scan = sim::errorStats(scan_errors).scaled(1e3);
      std::printf("%-13s %-12s %7zu | %9.2f %9.2f | %9.3f %9.3f | %9.3f %9.3f\n", model.name.c_str(),
                  motion.name, corrected.points.size(), raw.rms, raw.max, fixed.rms, fixed.max, scan.rms,
                  scan.max);
    }
  }
  return 0;
}
