// Test support: closed-form truth from the simulator, fed to the core the way tf knots will be.
#pragma once

#include <mrpt/poses/CPose3D.h>

#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::test {

/// Epoch of simulated time [ns] (an ordinary ROS time), and one millimetre [m].
constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;
constexpr double kMm = 1e-3;

/// The planar pose as an MRPT pose (z = 0, yaw only).
mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose);

/// Samples `trajectory` every `period` [s] over [begin, end] (both included) as pose samples stamped
/// epoch + t.
core::PoseSamples sampleTrajectory(const sim::Trajectory& trajectory, core::TimeNs epoch, double begin,
                                   double end, double period);

/// The true position of every corrected point: its beam's true world hit, in the laser frame at the
/// reference time (laser = base(t_ref) (+) mount), computed with the simulator's own geometry.
std::vector<Eigen::Vector2d> truePointsAtReference(const sim::SimulatedScan& simulated,
                                                   const core::DeskewedScan& corrected,
                                                   const sim::Trajectory& trajectory, const sim::Pose2& mount,
                                                   core::TimeNs epoch);

using sim::ErrorStats;
using sim::errorStats;

/// Per point: |corrected - truth| in the x-y plane [m].
std::vector<double> pointErrors(const core::DeskewedScan& corrected,
                                const std::vector<Eigen::Vector2d>& truth);

}  // namespace lidar_deskew::test

namespace lidar_deskew::test {

/// A motion source answering from the simulator's closed-form trajectory at any time in
/// [epoch + begin, epoch + end], with no sample times (so knots fall only on the knot grid).
class ClosedFormMotion final : public core::MotionSource {
 public:
  ClosedFormMotion(const sim::Trajectory& trajectory, core::TimeNs epoch, double begin, double end)
      : trajectory_(trajectory), epoch_(epoch), begin_(begin), end_(end) {}
  mrpt::poses::CPose3D basePose(core::TimeNs time) const override;

 private:
  const sim::Trajectory& trajectory_;
  core::TimeNs epoch_;
  double begin_, end_;
};

/// Raw beams as points (eq. 6, no correction), in the same order as `corrected`'s points.
std::vector<Eigen::Vector2d> rawPoints(const core::PlanarScan& scan, const core::DeskewedScan& corrected);

}  // namespace lidar_deskew::test
