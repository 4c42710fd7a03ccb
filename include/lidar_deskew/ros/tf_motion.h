// A core::MotionSource answered by a tf2::BufferCore (DESIGN §3): the base pose in the fixed frame.
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <tf2/buffer_core.h>

#include <deque>
#include <string>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::ros_adapter {

/// Looks up fixed_frame -> base_frame in a tf2 buffer. tf2 interpolates linearly between its samples;
/// the times of those samples, when fed through addSampleTime(), become knots of the correction so
/// that knots reproduce per-beam lookups exactly. Never extrapolates: times tf does not cover throw
/// core::MotionUnavailable with tf2's message.
class TfMotionSource final : public core::MotionSource {
 public:
  TfMotionSource(const tf2::BufferCore& buffer, std::string fixed_frame, std::string base_frame)
      : buffer_(buffer), fixed_frame_(std::move(fixed_frame)), base_frame_(std::move(base_frame)) {}

  mrpt::poses::CPose3D basePose(core::TimeNs time) const override;
  void appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                         std::vector<core::TimeNs>& times) const override;

  /// Call with every non-static transform given to the buffer: records the stamps of those on the
  /// fixed -> base chain (their times become knots), and whether fixed -> base is one direct link, in
  /// which case those stamps are all the chain's samples (sampleTimesComplete). Keeps the newest 4096.
  void observe(const geometry_msgs::TransformStamped& transform);
  /// Records a sample time of the chain directly (out-of-order and repeated times are fine).
  void addSampleTime(core::TimeNs time);
  /// Forgets sample times and what was learnt about the chain (tf cache cleared).
  void clearSampleTimes();
  bool sampleTimesComplete() const override { return direct_link_seen_ && !other_link_seen_; }
  /// Over the recorded sample times of the chain (for a longer chain, the union of its links' stamps).
  core::TimeNs longestGap(core::TimeNs begin, core::TimeNs end) const override;

  const std::string& fixedFrame() const { return fixed_frame_; }
  const std::string& baseFrame() const { return base_frame_; }

 private:
  static constexpr std::size_t kCapacity = 4096;
  const tf2::BufferCore& buffer_;
  std::string fixed_frame_;
  std::string base_frame_;
  std::deque<core::TimeNs> sample_times_;  // sorted, unique
  bool direct_link_seen_ = false;          // a dynamic fixed -> base transform arrived
  bool other_link_seen_ = false;           // base moved through another parent: a longer chain
};

}  // namespace lidar_deskew::ros_adapter
