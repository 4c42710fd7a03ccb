#include "lidar_deskew/ros/tf_motion.h"

#include <stdexcept>

#include <algorithm>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {

mrpt::poses::CPose3D TfMotionSource::basePose(core::TimeNs time) const {
  if (time < 0 || time >= (static_cast<core::TimeNs>(1) << 32) * 1'000'000'000) {
    throw core::MotionUnavailable(time, "time outside the range of ROS time");
  }
  try {
    return toPose(buffer_->lookupTransform(fixed_frame_, base_frame_, toRosTime(time)).transform);
  } catch (const std::exception& error) {  // tf2's, or ros::Duration's "out of dual 32-bit range"
    throw core::MotionUnavailable(time, error.what());
  }
}

void TfMotionSource::appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                                       std::vector<core::TimeNs>& times) const {
  auto it = std::upper_bound(sample_times_.begin(), sample_times_.end(), begin);
  for (; it != sample_times_.end() && *it < end; ++it)
    times.push_back(*it);
}

core::TimeNs TfMotionSource::longestGap(core::TimeNs begin, core::TimeNs end) const {
  return core::longestGapOf(sample_times_.begin(), sample_times_.end(), begin, end,
                            [](core::TimeNs time) { return time; });
}

void TfMotionSource::addSampleTime(core::TimeNs time) {
  if (sample_times_.empty() || time > sample_times_.back()) {
    sample_times_.push_back(time);
  } else {
    const auto it = std::lower_bound(sample_times_.begin(), sample_times_.end(), time);
    if (it == sample_times_.end() || *it != time)
      sample_times_.insert(it, time);
  }
  while (sample_times_.back() - sample_times_.front() > retention_)
    sample_times_.pop_front();
}

}  // namespace lidar_deskew::ros_adapter
