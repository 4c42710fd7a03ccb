// Where the robot base was: the motion source interface and a sampled implementation (docs/DESIGN.md §5).
#pragma once

#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <iterator>
#include <vector>

#include "lidar_deskew/core/types.h"

namespace lidar_deskew::core {

/// Answers "pose of the base in the fixed frame at time t". The tf2 adapter, the bag tool, tests and
/// tools implement it.
class MotionSource {
 public:
  virtual ~MotionSource() = default;

  /// Pose of the base frame in the fixed frame at `time` [ns].
  /// Throws MotionUnavailable when `time` is outside what the source covers. Never extrapolates.
  virtual mrpt::poses::CPose3D basePose(TimeNs time) const = 0;

  /// basePose(time) as its rotation matrix and translation [m], bit for bit, without the CPose3D (the
  /// twist fit and the knots read them). Throws as basePose. Default: from basePose().
  virtual void baseTransform(TimeNs time, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const;

  /// Appends the times [ns] strictly inside (begin, end) at which the source's motion model changes
  /// slope (its own samples). The correction places interpolation knots there too, so piecewise
  /// motion is reproduced exactly. Default: none known.
  virtual void appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const;

  /// True when the source's motion is linear (lerp + slerp) between the times appendSampleTimes
  /// reports, so knots there reproduce it exactly and no others are needed. Default: false.
  virtual bool sampleTimesComplete() const { return false; }

  /// True when the source's motion is a constant body twist (a screw: an arc in the plane) between the
  /// times appendSampleTimes reports: knots there, with screw segments between them, reproduce it
  /// exactly (KnotTrajectory, planar motion). Default: false.
  virtual bool screwsBetweenSamples() const { return false; }

  /// True when the source's motion between any two close times is nearer a screw through its poses there
  /// than a straight line (a fitted twist): KnotTrajectory then joins every pair of knots by a screw
  /// (planar motion). Default: false (tf2's own straight lines).
  virtual bool screwsBetweenKnots() const { return false; }

  /// [s] The knot spacing KnotTrajectory uses between the source's samples when its motion there is not
  /// a screw: `requested` (the knot_interval parameter), or less where the source knows that its twist
  /// changes so fast that screws between knots that far apart would stray from it. Default: requested.
  virtual double knotInterval(double requested) const { return requested; }

  /// [ns] The longest interval between consecutive samples of the source that overlaps [begin, end]:
  /// the source interpolates across it linearly, whatever the robot did meanwhile. 0 for continuous
  /// sources (the default). Gaps before the first or after the last sample are not counted: there
  /// the source does not answer at all.
  virtual TimeNs longestGap(TimeNs /*begin*/, TimeNs /*end*/) const { return 0; }
};

/// longestGap() over sample times sorted ascending in [first, last); `time_of` gives an element's
/// time [ns]. Pairs run from the last sample at or before `begin` while a pair starts before `end`.
template <typename It, typename TimeOf>
TimeNs longestGapOf(It first, It last, TimeNs begin, TimeNs end, TimeOf time_of) {
  It it = std::upper_bound(first, last, begin,
                           [&](TimeNs time, const auto& sample) { return time < time_of(sample); });
  if (it != first)
    --it;
  TimeNs longest = 0;
  for (; it != last && std::next(it) != last && time_of(*it) < end; ++it)
    longest = std::max(longest, time_of(*std::next(it)) - time_of(*it));
  return longest;
}

/// Interpolates between two poses like tf2 does: translation linearly, rotation by slerp on the
/// shortest arc. `fraction` in [0, 1]: 0 gives `from`, 1 gives `to`.
mrpt::poses::CPose3D interpolatePose(const mrpt::poses::CPose3D& from, const mrpt::poses::CPose3D& to,
                                     double fraction);

/// A motion source over time-stamped pose samples, interpolated between neighbours like tf2
/// (interpolatePose). For planar (CPose2D) samples this is SE(2) interpolation: x, y linear, yaw
/// along the shorter way. Exact at the samples; times outside [first, last] are not covered.
class PoseSamples final : public MotionSource {
 public:
  /// Appends a sample. Times must strictly increase; throws InvalidInput("time") otherwise, and
  /// InvalidInput("pose") for non-finite poses.
  void add(TimeNs time, const mrpt::poses::CPose3D& base_pose);
  void add(TimeNs time, const mrpt::poses::CPose2D& base_pose);

  void clear() { samples_.clear(); }
  bool empty() const { return samples_.empty(); }
  std::size_t size() const { return samples_.size(); }
  /// [ns] first / last sample time. Precondition: not empty.
  TimeNs firstTime() const { return samples_.front().time; }
  TimeNs lastTime() const { return samples_.back().time; }
  /// True when basePose(time) would answer.
  bool covers(TimeNs time) const;

  mrpt::poses::CPose3D basePose(TimeNs time) const override;
  void appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const override;
  bool sampleTimesComplete() const override { return true; }
  TimeNs longestGap(TimeNs begin, TimeNs end) const override;

 private:
  struct Sample {
    TimeNs time;
    mrpt::poses::CPose3D pose;
  };
  std::vector<Sample> samples_;
};

}  // namespace lidar_deskew::core
