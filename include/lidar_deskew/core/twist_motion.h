// Motion between odometry samples better than tf's straight line (docs/DESIGN.md §5): the twist between
// consecutive samples, fit over their neighbours, integrated on SE(3).
#pragma once

#include <Eigen/Core>

#include <array>
#include <deque>
#include <vector>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::core {

/// A twist in the body frame: (v, w) [m/s, rad/s], se(3) coordinates (translation part first).
using Twist = Eigen::Matrix<double, 6, 1>;

/// SE(3) exponential of `xi` (rho, phi) as (rotation, translation); exact, with series for small angles.
void se3Exp(const Twist& xi, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation);
/// Its inverse for rotations below pi: the twist whose exponential is (rotation, translation).
Twist se3Log(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation);
/// The Lie bracket [a, b] of se(3): (phi_a x rho_b - phi_b x rho_a, phi_a x phi_b).
Twist se3Bracket(const Twist& a, const Twist& b);

/// The base motion between a sampled source's samples (tf's, or PoseSamples'), as a body twist that is
/// constant or changes linearly over each sample interval, integrated on SE(3):
///
/// - Each interval k between samples k and k+1 has a mean twist m_k = Log(T_k^-1 T_k+1) / h_k.
/// - Each twist component of each interval the sweep touches is fit by a straight line in time over
///   the intervals around it: the widest window (up to smoothing_window, centred) in which a line
///   explains the means within the odometry's noise; if none does, a line through the interval and two
///   neighbours on one side that does (a change of slope beside it); else the interval's own mean
///   (a change of twist at its sample: an arc through both samples).
/// - The noise is estimated from the samples themselves: how far each interval's mean lies from the best of
///   the simplest local models (constant over two intervals, straight over three, a quartic over six),
///   a median over the intervals of about a second before the sweep to the window after it. Exact samples
///   give a noise of 0 (to a floor of 1e-5 m or 1e-6 rad per interval), so every sample is then followed
///   exactly.
/// - Over an interval the fitted twist is integrated to second order (two Magnus terms) such that its
///   end lies where the fitted mean twist takes it.
///
/// Exact for constant linear and angular velocity (an arc; its twist is the same on every interval) and,
/// with exact samples, for a twist that changes linearly or steps at a sample; with noisy samples the
/// motion over the sweep is a least-squares fit, not a curve through each sample.
class TwistMotion final : public MotionSource {
 public:
  /// `smoothing_window` [s]: the longest time over which interval twists are fit together (0: only
  /// exact lines and steps, every sample followed). Throws InvalidInput("smoothing_window") when
  /// negative, not finite or above 10 s.
  explicit TwistMotion(double smoothing_window = 0.6);
  /// Throws InvalidInput("smoothing_window") when `smoothing_window` [s] is negative, not finite or above 10.
  static void checkWindow(double smoothing_window);

  /// Fits the motion of `raw` over [begin, end] from its samples (MotionSource::appendSampleTimes and
  /// basePose at those times). Returns *this, or `raw` itself when raw reports no samples at or before
  /// `begin` and at or after `end` that it can answer (a continuous source; tf beyond its newest
  /// sample, extrapolated): then its own motion is used as it is. Throws what raw.basePose throws for
  /// a time in [begin, end].
  const MotionSource& prepare(const MotionSource& raw, TimeNs begin, TimeNs end);

  /// The fitted pose at `time` within the prepared span's sample intervals; throws MotionUnavailable
  /// elsewhere.
  mrpt::poses::CPose3D basePose(TimeNs time) const override;
  /// The sample times in (begin, end): the fitted motion's pieces end there.
  void appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const override;
  TimeNs longestGap(TimeNs begin, TimeNs end) const override;
  /// True when every fitted piece has a constant twist (exact samples without a changing twist, and
  /// no smoothing): its pieces are screws.
  bool screwsBetweenSamples() const override { return screws_; }
  bool screwsBetweenKnots() const override { return true; }

  /// The noise [m/s, rad/s] per twist component estimated for the last prepare() (0 when exact or
  /// too few samples), and how many of its intervals were smoothed (fitted twist off their own mean
  /// by more than the floor).
  const Twist& estimatedNoise() const { return noise_; }
  std::size_t smoothedIntervals() const { return smoothed_intervals_; }

 private:
  struct Sample {
    TimeNs time;
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    Twist mean;  // of the interval to the sample at mean_until (-1: not computed yet)
    TimeNs mean_until;
  };
  /// One fitted interval: starts at `time`, lasts `duration` [s]; the twist at t' [s] into it is
  /// start_twist + t' slope; pose there = start pose * Exp(Omega(t')).
  struct Piece {
    TimeNs time;
    double duration;
    Twist start_twist;
    Twist slope;
    Eigen::Matrix3d rotation;  // fitted pose at the piece's start
    Eigen::Vector3d translation;
    /// Omega(t') = start t' + slope t'^2 / 2 + t'^3 / 12 [start, slope]: the motion t' [s] into the piece.
    Twist omega(double tau) const;
  };

  /// The first cached sample at or after `time`.
  std::deque<Sample>::iterator cachedAt(TimeNs time);
  bool gatherSamples(const MotionSource& raw, TimeNs begin, TimeNs end);
  void estimateNoise();
  /// Fitted (mean twist, slope) of interval j, component c.
  void fitInterval(std::size_t j, int c, double& mean, double& slope) const;

  double smoothing_window_;
  const MotionSource* raw_ = nullptr;
  std::vector<Sample> samples_;
  std::deque<Sample> cache_;  // the source's answers at its sample times, sorted
  const MotionSource* cache_source_ = nullptr;
  TimeNs cache_begin_ = 0;
  std::vector<TimeNs> times_;      // scratch: sample times
  std::vector<Twist> means_;       // per interval
  std::vector<double> durations_;  // [s] per interval
  std::vector<double> centres_;    // [s] interval mid times from the first sample
  Twist noise_ = Twist::Zero();
  Twist floor_ = Twist::Zero();
  std::vector<Piece> pieces_;
  Eigen::Matrix3d end_rotation_;  // fitted pose at end_time_, the last piece's end
  Eigen::Vector3d end_translation_;
  TimeNs end_time_ = 0;
  std::size_t smoothed_intervals_ = 0;
  bool screws_ = false;
  std::vector<double> scratch_;  // estimateNoise()'s buffer for medians
  std::vector<double> minima_;   // estimateNoise()'s smallest residual per interval, a column per component
  std::vector<Twist> step_, chord_, curve_;  // estimateNoise()'s residuals per stencil
};

}  // namespace lidar_deskew::core
