#include "lidar_deskew/ros/tf_motion.h"

#include <stdexcept>

#include <algorithm>
#include <cmath>

#include <tf2/LinearMath/Matrix3x3.h>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

/// One step of tf2's walk up the tree (BufferCore's TransformAccum::accum): `link` composed on the left
/// of what was accumulated.
void accumulate(const OneLinkChain::Link& link, OneLinkChain::Link& accumulated) {
  accumulated.translation = tf2::quatRotate(link.rotation, accumulated.translation) + link.translation;
  accumulated.rotation = link.rotation * accumulated.rotation;
}

/// [s] A duration of `ns` >= 0 as ros::Duration::toSec gives it: whole seconds plus 1e-9 times the rest.
double durationSeconds(core::TimeNs ns) {
  return static_cast<double>(ns / 1'000'000'000) + 1e-9 * static_cast<double>(ns % 1'000'000'000);
}

/// tf2::slerp(from, to, t) at t = +0 (a sample's own stamp), to the bit: its sines of (1 - t) theta
/// and t theta are those of theta and of +0 (theta is finite and not negative), so sin runs once.
tf2::Quaternion slerpAtStart(const tf2::Quaternion& from, const tf2::Quaternion& to) {
  const tf2Scalar theta = from.angleShortestPath(to) / tf2Scalar(2.0);
  if (!(theta > tf2Scalar(0.0) && std::isfinite(theta)))
    return tf2::slerp(from, to, tf2Scalar(0.0));
  const tf2Scalar sine = tf2Sin(theta);
  const tf2Scalar d = tf2Scalar(1.0) / sine;
  const tf2Scalar s0 = sine, s1 = 0.0;
  if (from.dot(to) < 0)
    return tf2::Quaternion((from.x() * s0 + -to.x() * s1) * d, (from.y() * s0 + -to.y() * s1) * d,
                           (from.z() * s0 + -to.z() * s1) * d, (from.w() * s0 + -to.w() * s1) * d);
  return tf2::Quaternion((from.x() * s0 + to.x() * s1) * d, (from.y() * s0 + to.y() * s1) * d,
                         (from.z() * s0 + to.z() * s1) * d, (from.w() * s0 + to.w() * s1) * d);
}

OneLinkChain::Link identityLink() {
  return {tf2::Quaternion(0.0, 0.0, 0.0, 1.0), tf2::Vector3(0.0, 0.0, 0.0)};
}

}  // namespace

void OneLinkChain::setChain(const std::string& child, const std::string& parent, std::vector<Link> below,
                            std::vector<Link> above, FixedLink fixed_link, core::TimeNs newest) {
  if (!valid_ || child != child_ || parent != parent_) {
    // Another dynamic link: its samples start with the next one in order (tf2 may hold older ones).
    samples_.clear();
    child_ = child;
    parent_ = parent;
    newest_ = newest;
    complete_ = newest == 0;
    before_ = newest;
  }
  valid_ = true;
  below_ = identityLink();
  for (const Link& link : below)
    accumulate(link, below_);
  above_ = std::move(above);
  fixed_link_ = fixed_link;
}

void OneLinkChain::clearChain() {
  valid_ = false;
  samples_.clear();
}

void OneLinkChain::addFixedLinkStamp(core::TimeNs stamp) {
  // As tf2's TimeCache keeps its stamps: in order (no repeats: tf2 refuses them), pruned by the newest.
  fixed_link_stamps_.insert(std::upper_bound(fixed_link_stamps_.begin(), fixed_link_stamps_.end(), stamp),
                            stamp);
  while (fixed_link_stamps_.front() + cache_ < fixed_link_stamps_.back())
    fixed_link_stamps_.pop_front();
}

void OneLinkChain::clearSamples() {
  samples_.clear();
  fixed_link_stamps_.clear();
  newest_ = 0;
  complete_ = true;
  before_ = 0;
}

void OneLinkChain::add(const std::string& child, const std::string& parent, core::TimeNs stamp,
                       const geometry_msgs::Transform& transform) {
  if (!valid_ || child != child_)
    return;
  if (parent != parent_ || stamp <= newest_) {
    // Out of order, repeated, or from another parent: tf2's samples around it are not all kept here.
    // Kept again from the next one in order.
    newest_ = std::max(newest_, stamp);
    samples_.clear();
    complete_ = false;
    before_ = newest_;
    return;
  }
  newest_ = stamp;
  // As tf2's TransformStorage holds it.
  samples_.push_back(
      Sample{stamp,
             {tf2::Quaternion(transform.rotation.x, transform.rotation.y, transform.rotation.z,
                              transform.rotation.w),
              tf2::Vector3(transform.translation.x, transform.translation.y, transform.translation.z)}});
  // tf2's TimeCache::pruneList: samples older than the cache time before the newest.
  while (samples_.front().stamp + cache_ < stamp) {
    samples_.pop_front();
    newer_hint_ -= newer_hint_ > 0 ? 1 : 0;
  }
  if (!complete_ && before_ + cache_ < stamp)
    complete_ = true;  // tf2 pruned the samples before the first kept too
}

bool OneLinkChain::answer(core::TimeNs time, geometry_msgs::Transform& out) const {
  if (!answers(time))
    return false;
  // tf2's TimeCache::findClosest and getData: its newest and earliest samples as they are, else the
  // pair around `time` (the older one at or before it) interpolated, even at a sample's own stamp.
  Link link;
  if (time == samples_.back().stamp) {
    link = samples_.back().link;
  } else if (time == samples_.front().stamp && complete_) {
    link = samples_.front().link;
  } else {
    // The first sample after `time` (there is one, and one at or before it): usually the one after
    // the last found, or that one again (the fit asks for consecutive new samples), else searched.
    const std::size_t size = samples_.size();
    std::size_t newer = std::clamp<std::size_t>(newer_hint_, 1, size - 1);
    const auto brackets = [&](std::size_t index) {
      return samples_[index - 1].stamp <= time && time < samples_[index].stamp;
    };
    if (!brackets(newer)) {
      if (newer + 1 < size && brackets(newer + 1)) {
        ++newer;
      } else {
        // The first index in [1, size) whose stamp is after `time` (std::upper_bound's).
        std::size_t low = 1, count = size - 1;
        while (count > 0) {
          const std::size_t half = count / 2;
          if (time < samples_[low + half].stamp) {
            count = half;
          } else {
            low += half + 1;
            count -= half + 1;
          }
        }
        newer = low;
      }
    }
    newer_hint_ = newer;
    const Sample& one = samples_[newer - 1];
    const Sample& two = samples_[newer];
    // TimeCache::interpolate: the ratio of ros::Durations' seconds.
    // At one's own stamp (the fit asks there): 0 s over a positive duration, +0.
    const tf2Scalar ratio = time == one.stamp
                                ? tf2Scalar(0.0)
                                : durationSeconds(time - one.stamp) / durationSeconds(two.stamp - one.stamp);
    link.translation.setInterpolate3(one.link.translation, two.link.translation, ratio);
    link.rotation = time == one.stamp ? slerpAtStart(one.link.rotation, two.link.rotation)
                                      : tf2::slerp(one.link.rotation, two.link.rotation, ratio);
  }
  // The walk from the base up: below the link, the link, above it.
  Link accumulated = below_;
  accumulate(link, accumulated);
  for (const Link& static_link : above_)
    accumulate(static_link, accumulated);
  // tf2's walk reads the fixed frame's link (TimeCache::getData): a static one always answers, a
  // dynamic one at its single stamp or between its earliest and newest.
  const bool fixed_link_answers = fixed_link_ == FixedLink::kStatic ||
                                  (fixed_link_ == FixedLink::kDynamic && !fixed_link_stamps_.empty() &&
                                   (fixed_link_stamps_.size() == 1 ? time == fixed_link_stamps_.front()
                                                                   : time >= fixed_link_stamps_.front() &&
                                                                         time <= fixed_link_stamps_.back()));
  if (!fixed_link_answers) {
    // tf2's walk ended at the fixed frame, as at a root: its "full path" ending, the target's walk empty.
    const Link target = identityLink();
    const tf2::Quaternion inverse_target_rotation = target.rotation.inverse();
    const tf2::Vector3 inverse_target_translation =
        tf2::quatRotate(inverse_target_rotation, -target.translation);
    accumulated.translation =
        tf2::quatRotate(inverse_target_rotation, accumulated.translation) + inverse_target_translation;
    accumulated.rotation = inverse_target_rotation * accumulated.rotation;
  }
  out.translation.x = accumulated.translation.x();
  out.translation.y = accumulated.translation.y();
  out.translation.z = accumulated.translation.z();
  out.rotation.x = accumulated.rotation.x();
  out.rotation.y = accumulated.rotation.y();
  out.rotation.z = accumulated.rotation.z();
  out.rotation.w = accumulated.rotation.w();
  return true;
}

geometry_msgs::Transform TfMotionSource::transformAt(core::TimeNs time) const {
  if (time < 0 || time >= (static_cast<core::TimeNs>(1) << 32) * 1'000'000'000) {
    throw core::MotionUnavailable(time, "time outside the range of ROS time");
  }
  if (geometry_msgs::Transform answered; chain_.answer(time, answered))
    return answered;
  ++tf_lookups_;
  try {
    return buffer_->lookupTransform(fixed_frame_, base_frame_, toRosTime(time)).transform;
  } catch (const std::exception& error) {  // tf2's, or ros::Duration's "out of dual 32-bit range"
    throw core::MotionUnavailable(time, error.what());
  }
}

mrpt::poses::CPose3D TfMotionSource::basePose(core::TimeNs time) const { return toPose(transformAt(time)); }

void TfMotionSource::baseTransform(core::TimeNs time, Eigen::Matrix3d& rotation,
                                   Eigen::Vector3d& translation) const {
  // As toPose() converts it: tf2's rotation matrix of the quaternion, and the translation, copied.
  const geometry_msgs::Transform transform = transformAt(time);
  const tf2::Matrix3x3 basis(tf2::Quaternion(transform.rotation.x, transform.rotation.y, transform.rotation.z,
                                             transform.rotation.w));
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      rotation(r, c) = basis[r][c];
  }
  translation = Eigen::Vector3d(transform.translation.x, transform.translation.y, transform.translation.z);
}

void TfMotionSource::appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                                       std::vector<core::TimeNs>& times) const {
  const auto from = std::upper_bound(keptTimes(), sample_times_.end(), begin);
  times.insert(times.end(), from, std::lower_bound(from, sample_times_.end(), end));
}

core::TimeNs TfMotionSource::longestGap(core::TimeNs begin, core::TimeNs end) const {
  return core::longestGapOf(keptTimes(), sample_times_.end(), begin, end,
                            [](core::TimeNs time) { return time; });
}

void TfMotionSource::addSampleTime(core::TimeNs time) {
  if (sample_front_ == sample_times_.size() || time > sample_times_.back()) {
    sample_times_.push_back(time);
  } else {
    const auto it = std::lower_bound(keptTimes(), sample_times_.cend(), time);
    if (it == sample_times_.end() || *it != time)
      sample_times_.insert(it, time);
  }
  while (sample_times_.back() - sample_times_[sample_front_] > retention_)
    ++sample_front_;
  if (2 * sample_front_ >= sample_times_.size()) {  // (each time moved once, on average)
    sample_times_.erase(sample_times_.begin(), keptTimes());
    sample_front_ = 0;
  }
}

}  // namespace lidar_deskew::ros_adapter
