// A core::MotionSource answered by a tf2::BufferCore (docs/DESIGN.md §5): the base pose in the
// fixed frame.
#pragma once

#include <geometry_msgs/Transform.h>
#include <tf2/LinearMath/Quaternion.h>
#include <tf2/LinearMath/Vector3.h>
#include <tf2/buffer_core.h>

#include <algorithm>
#include <cstddef>
#include <deque>
#include <string>
#include <vector>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::ros_adapter {

/// fixed -> base where tf2's walk from the base up to the fixed frame crosses one dynamic link, with
/// any static links below and above it (docs/DESIGN.md §3): that link's samples kept as tf2 took them,
/// and answered as tf2's lookupTransform answers, to the bit (its choice of samples, its lerp + slerp,
/// its composition along the walk), without a lookup. Where its samples cannot say what tf2 holds (a
/// sample arriving out of order, from another parent, before the first kept one) it answers nothing
/// and the caller asks tf2.
class OneLinkChain {
 public:
  /// A link as tf2 holds it: the child's rotation and origin in the parent.
  struct Link {
    tf2::Quaternion rotation;
    tf2::Vector3 translation;
  };
  /// The fixed frame's own link, where tf2's walk up from the base ends: at a static link or a dynamic
  /// one that answers the time (the fixed frame's pose), else (a root) composed with the identity.
  enum class FixedLink { kNone, kStatic, kDynamic };
  /// `cache` [ns]: the tf2 buffer's cache time (its samples are pruned alike).
  explicit OneLinkChain(core::TimeNs cache) : cache_(cache) {}

  /// The walk is `below` (static links from the base up to `child`), parent -> child on /tf, then
  /// `above` (static links from `parent` up to the fixed frame), then the fixed frame's link.
  /// `newest` [ns]: the newest stamp tf2 holds of child (0: none). The samples are kept when the
  /// dynamic link is the one before.
  void setChain(const std::string& child, const std::string& parent, std::vector<Link> below,
                std::vector<Link> above, FixedLink fixed_link, core::TimeNs newest);
  /// fixed -> base is not such a walk: nothing is answered.
  void clearChain();
  /// A transform of `child` that tf2 took, in arrival order (others' are ignored).
  void add(const std::string& child, const std::string& parent, core::TimeNs stamp,
           const geometry_msgs::Transform& transform);
  /// A stamp [ns] tf2 took of the fixed frame's own link on /tf, in arrival order.
  void addFixedLinkStamp(core::TimeNs stamp);
  /// tf2's dynamic caches were cleared.
  void clearSamples();
  /// fixed -> base at `time` [ns] as tf2 would answer it, when the samples kept say so; else false.
  bool answer(core::TimeNs time, geometry_msgs::Transform& out) const;
  /// True when answer() answers `time` [ns] (tf2 then answers it too).
  bool answers(core::TimeNs time) const {
    return valid_ && !samples_.empty() && time >= samples_.front().stamp && time <= samples_.back().stamp;
  }
  /// [ns] tf2's latest common time of fixed -> base (the dynamic link's newest stamp: statics have
  /// none), when the samples kept say so; else 0.
  core::TimeNs newest() const { return valid_ && !samples_.empty() ? samples_.back().stamp : 0; }
  /// The samples kept.
  std::size_t size() const { return samples_.size(); }

 private:
  struct Sample {
    core::TimeNs stamp;
    Link link;
  };
  /// Samples in a ring buffer (a power-of-two capacity, grown when full): pushed at the back, popped at
  /// the front, read by index without a deque's block arithmetic.
  class SampleRing {
   public:
    void clear() { first_ = count_ = 0; }
    bool empty() const { return count_ == 0; }
    std::size_t size() const { return count_; }
    const Sample& operator[](std::size_t index) const { return ring_[(first_ + index) & (ring_.size() - 1)]; }
    const Sample& front() const { return (*this)[0]; }
    const Sample& back() const { return (*this)[count_ - 1]; }
    void pop_front() {
      first_ = (first_ + 1) & (ring_.size() - 1);
      --count_;
    }
    void push_back(const Sample& sample) {
      if (count_ == ring_.size()) {
        std::vector<Sample> grown(std::max<std::size_t>(64, 2 * ring_.size()));
        for (std::size_t i = 0; i < count_; ++i)
          grown[i] = (*this)[i];
        ring_.swap(grown);
        first_ = 0;
      }
      ring_[(first_ + count_) & (ring_.size() - 1)] = sample;
      ++count_;
    }

   private:
    std::vector<Sample> ring_;
    std::size_t first_ = 0, count_ = 0;
  };
  core::TimeNs cache_;
  bool valid_ = false;
  std::string child_, parent_;
  Link below_;               // the base in child, accumulated as tf2 does from the base up
  std::vector<Link> above_;  // from parent up
  FixedLink fixed_link_ = FixedLink::kNone;
  std::deque<core::TimeNs> fixed_link_stamps_;  // sorted: those tf2 holds of the fixed frame's link
  SampleRing samples_;  // in stamp order: every sample tf2 holds of child from the first on
  mutable std::size_t newer_hint_ = 0;  // answer(): the index of the sample after the last time asked
  core::TimeNs newest_ = 0;     // [ns] the newest stamp tf2 took of child (0: none)
  /// True when tf2 holds no sample of child before the first kept (tf2 answers its earliest as it is).
  bool complete_ = true;
  core::TimeNs before_ = 0;  // [ns] else: the newest such sample (pruned like tf2's: then complete)
};

/// Looks up fixed_frame -> base_frame in a tf2 buffer. tf2 interpolates linearly between its samples;
/// the times of those samples, when fed through addSampleTime(), become knots of the correction so
/// that knots reproduce per-beam lookups exactly. Never extrapolates: times tf does not cover throw
/// core::MotionUnavailable with tf2's message. TfFeed keeps one up to date, with a OneLinkChain that
/// answers without a lookup where it can; tests and benchmarks may fill one by hand.
class TfMotionSource final : public core::MotionSource {
 public:
  /// `retention` [ns]: sample times older than the newest one by more than this are forgotten (make
  /// it the buffer's cache time: tf2 forgets those samples too).
  TfMotionSource(const tf2::BufferCore& buffer, std::string fixed_frame, std::string base_frame,
                 core::TimeNs retention = 10'000'000'000)
      : buffer_(&buffer),
        fixed_frame_(std::move(fixed_frame)),
        base_frame_(std::move(base_frame)),
        retention_(retention),
        chain_(retention) {}

  mrpt::poses::CPose3D basePose(core::TimeNs time) const override;
  void baseTransform(core::TimeNs time, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const override;
  void appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                         std::vector<core::TimeNs>& times) const override;
  /// True when setSingleLink(true) was said: fixed -> base is one dynamic link, so its stamps are all
  /// the chain's samples and tf2 is linear between them.
  bool sampleTimesComplete() const override { return single_link_; }
  /// Over the recorded sample times of the chain (for a longer chain, the union of its links' stamps).
  core::TimeNs longestGap(core::TimeNs begin, core::TimeNs end) const override;

  /// Records a sample time of the chain (out-of-order and repeated times are fine).
  void addSampleTime(core::TimeNs time);
  /// Forgets the samples (tf's dynamic cache cleared): their times and the one-link chain's.
  void clearSamples() {
    sample_times_.clear();
    sample_front_ = 0;
    chain_.clearSamples();
  }
  void setSingleLink(bool single_link) { single_link_ = single_link; }
  /// Answers from `buffer` from now on (the owner replaced its buffer).
  void setBuffer(const tf2::BufferCore& buffer) { buffer_ = &buffer; }

  /// The one-link chain that answers basePose without tf2 where it can (TfFeed keeps it).
  OneLinkChain& chain() { return chain_; }
  const OneLinkChain& chain() const { return chain_; }
  /// How many times basePose asked tf2 (the one-link chain answered the others).
  std::size_t tfLookups() const { return tf_lookups_; }

  const std::string& fixedFrame() const { return fixed_frame_; }
  const std::string& baseFrame() const { return base_frame_; }

 private:
  /// fixed -> base at `time` as tf2 answers it (the one-link chain where it can).
  geometry_msgs::Transform transformAt(core::TimeNs time) const;

  const tf2::BufferCore* buffer_;
  std::string fixed_frame_;
  std::string base_frame_;
  core::TimeNs retention_;
  /// From sample_front_ on: sorted, unique, within retention_ of the newest. Those before are forgotten
  /// and erased in one go once they are as many as the rest (a vector: searched faster than a deque).
  std::vector<core::TimeNs> sample_times_;
  std::size_t sample_front_ = 0;
  /// The first kept of sample_times_.
  std::vector<core::TimeNs>::const_iterator keptTimes() const {
    return sample_times_.begin() + static_cast<std::ptrdiff_t>(sample_front_);
  }
  bool single_link_ = false;
  OneLinkChain chain_;
  mutable std::size_t tf_lookups_ = 0;
};

}  // namespace lidar_deskew::ros_adapter
