#include "lidar_deskew/core/motion.h"

#include <algorithm>
#include <cmath>

#include "pose_eigen.h"

namespace lidar_deskew::core {
namespace {

bool isFinite(const mrpt::poses::CPose3D& pose) {
  return detail::rotationOf(pose).allFinite() && detail::translationOf(pose).allFinite();
}

}  // namespace

void MotionSource::baseTransform(TimeNs time, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const {
  const mrpt::poses::CPose3D pose = basePose(time);
  rotation = detail::rotationOf(pose);
  translation = detail::translationOf(pose);
}

void MotionSource::appendSampleTimes(TimeNs /*begin*/, TimeNs /*end*/, std::vector<TimeNs>& /*times*/) const {
}

mrpt::poses::CPose3D interpolatePose(const mrpt::poses::CPose3D& from, const mrpt::poses::CPose3D& to,
                                     double fraction) {
  const Eigen::Vector3d p0 = detail::translationOf(from);
  const Eigen::Vector3d p1 = detail::translationOf(to);
  // Eigen's slerp takes the shorter arc and stays accurate for tiny angles.
  const Eigen::Quaterniond q0(detail::rotationOf(from));
  const Eigen::Quaterniond q1(detail::rotationOf(to));
  const Eigen::Quaterniond rotation = q0.slerp(fraction, q1).normalized();
  return detail::poseOf(rotation.toRotationMatrix(), p0 + fraction * (p1 - p0));
}

void PoseSamples::add(TimeNs time, const mrpt::poses::CPose3D& base_pose) {
  if (!samples_.empty() && time <= samples_.back().time) {
    throw InvalidInput("time", "pose samples must have strictly increasing times: " + std::to_string(time) +
                                   " ns after " + std::to_string(samples_.back().time) + " ns");
  }
  if (!isFinite(base_pose))
    throw InvalidInput("pose", "pose sample is not finite");
  samples_.push_back({time, base_pose});
}

void PoseSamples::add(TimeNs time, const mrpt::poses::CPose2D& base_pose) {
  add(time, mrpt::poses::CPose3D(base_pose));
}

bool PoseSamples::covers(TimeNs time) const {
  return !samples_.empty() && time >= samples_.front().time && time <= samples_.back().time;
}

mrpt::poses::CPose3D PoseSamples::basePose(TimeNs time) const {
  if (!covers(time)) {
    throw MotionUnavailable(time, samples_.empty()
                                      ? "no pose samples"
                                      : "time " + std::to_string(time) + " ns is outside the pose samples [" +
                                            std::to_string(samples_.front().time) + ", " +
                                            std::to_string(samples_.back().time) + "] ns");
  }
  // First sample at or after `time`.
  const auto after = std::lower_bound(samples_.begin(), samples_.end(), time,
                                      [](const Sample& sample, TimeNs t) { return sample.time < t; });
  if (after->time == time)
    return after->pose;
  const auto before = after - 1;
  const double fraction =
      static_cast<double>(time - before->time) / static_cast<double>(after->time - before->time);
  return interpolatePose(before->pose, after->pose, fraction);
}

void PoseSamples::appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const {
  auto it = std::upper_bound(samples_.begin(), samples_.end(), begin,
                             [](TimeNs t, const Sample& sample) { return t < sample.time; });
  for (; it != samples_.end() && it->time < end; ++it)
    times.push_back(it->time);
}

TimeNs PoseSamples::longestGap(TimeNs begin, TimeNs end) const {
  return longestGapOf(samples_.begin(), samples_.end(), begin, end,
                      [](const Sample& sample) { return sample.time; });
}

}  // namespace lidar_deskew::core
