// A core::MotionSource answered by a tf2::BufferCore (docs/DESIGN.md §5): the base pose in the
// fixed frame.
#pragma once

#include <tf2/buffer_core.h>

#include <deque>
#include <string>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::ros_adapter {

/// Looks up fixed_frame -> base_frame in a tf2 buffer. tf2 interpolates linearly between its samples;
/// the times of those samples, when fed through addSampleTime(), become knots of the correction so
/// that knots reproduce per-beam lookups exactly. Never extrapolates: times tf does not cover throw
/// core::MotionUnavailable with tf2's message. TfFeed keeps one up to date; tests and benchmarks may
/// fill one by hand.
class TfMotionSource final : public core::MotionSource {
 public:
  /// `retention` [ns]: sample times older than the newest one by more than this are forgotten (make
  /// it the buffer's cache time: tf2 forgets those samples too).
  TfMotionSource(const tf2::BufferCore& buffer, std::string fixed_frame, std::string base_frame,
                 core::TimeNs retention = 10'000'000'000)
      : buffer_(&buffer),
        fixed_frame_(std::move(fixed_frame)),
        base_frame_(std::move(base_frame)),
        retention_(retention) {}

  mrpt::poses::CPose3D basePose(core::TimeNs time) const override;
  void appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                         std::vector<core::TimeNs>& times) const override;
  /// True when setSingleLink(true) was said: fixed -> base is one dynamic link, so its stamps are all
  /// the chain's samples and tf2 is linear between them.
  bool sampleTimesComplete() const override { return single_link_; }
  /// Over the recorded sample times of the chain (for a longer chain, the union of its links' stamps).
  core::TimeNs longestGap(core::TimeNs begin, core::TimeNs end) const override;

  /// Records a sample time of the chain (out-of-order and repeated times are fine).
  void addSampleTime(core::TimeNs time);
  /// Forgets the sample times (tf cache cleared).
  void clearSampleTimes() { sample_times_.clear(); }
  void setSingleLink(bool single_link) { single_link_ = single_link; }
  /// Answers from `buffer` from now on (the owner replaced its buffer).
  void setBuffer(const tf2::BufferCore& buffer) { buffer_ = &buffer; }

  const std::string& fixedFrame() const { return fixed_frame_; }
  const std::string& baseFrame() const { return base_frame_; }

 private:
  const tf2::BufferCore* buffer_;
  std::string fixed_frame_;
  std::string base_frame_;
  core::TimeNs retention_;
  std::deque<core::TimeNs> sample_times_;  // sorted, unique, within retention_ of the newest
  bool single_link_ = false;
};

}  // namespace lidar_deskew::ros_adapter
