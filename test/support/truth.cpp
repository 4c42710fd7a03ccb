#include "support/truth.h"

#include <cmath>

namespace lidar_deskew::test {

mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose) {
  return mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0);
}

core::PoseSamples sampleTrajectory(const sim::Trajectory& trajectory, core::TimeNs epoch, double begin,
                                   double end, double period) {
  core::PoseSamples samples;
  const long steps = std::lround(std::ceil((end - begin) / period));
  for (long k = 0; k <= steps; ++k) {
    const double t = std::min(begin + k * period, end);
    const core::TimeNs stamp = epoch + core::secondsToNs(t);
    if (!samples.empty() && stamp <= samples.lastTime())
      continue;
    samples.add(stamp, toMrpt(trajectory.pose(t)));
  }
  return samples;
}

std::vector<Eigen::Vector2d> truePointsAtReference(const sim::SimulatedScan& simulated,
                                                   const core::DeskewedScan& corrected,
                                                   const sim::Trajectory& trajectory, const sim::Pose2& mount,
                                                   core::TimeNs epoch) {
  const sim::Pose2 laser_at_reference =
      trajectory.pose(core::nsToSeconds(corrected.reference_time - epoch)).compose(mount);
  std::vector<Eigen::Vector2d> truth;
  truth.reserve(corrected.points.size());
  for (const core::DeskewedPoint& point : corrected.points) {
    truth.push_back(laser_at_reference.applyInverse(simulated.world_hits[point.beam_index]));
  }
  return truth;
}

std::vector<double> pointErrors(const core::DeskewedScan& corrected,
                                const std::vector<Eigen::Vector2d>& truth) {
  std::vector<double> errors;
  for (std::size_t j = 0; j < corrected.points.size(); ++j) {
    errors.push_back((corrected.points[j].position.head<2>() - truth[j]).norm());
  }
  return errors;
}

}  // namespace lidar_deskew::test

namespace lidar_deskew::test {

mrpt::poses::CPose3D ClosedFormMotion::basePose(core::TimeNs time) const {
  const double t = core::nsToSeconds(time - epoch_);
  if (t < begin_ - 1e-9 || t > end_ + 1e-9)
    throw core::MotionUnavailable(time, "outside the closed-form span");
  return toMrpt(trajectory_.pose(t));
}

std::vector<Eigen::Vector2d> rawPoints(const core::PlanarScan& scan, const core::DeskewedScan& corrected) {
  std::vector<Eigen::Vector2d> raw;
  for (const core::DeskewedPoint& point : corrected.points) {
    const double angle =
        static_cast<double>(scan.angle_min) + point.beam_index * static_cast<double>(scan.angle_increment);
    const double range = scan.ranges[point.beam_index];
    raw.emplace_back(range * std::cos(angle), range * std::sin(angle));
  }
  return raw;
}

}  // namespace lidar_deskew::test
