// Motion between odometry samples better than tf's straight line (docs/DESIGN.md §5): the twist between
// consecutive samples, fit over their neighbours, integrated on SE(3).
#pragma once

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <vector>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::core {

/// [s] The twist fit reads tf's samples at most this far before a sweep and after it (its look-ahead,
/// DeskewConfig::fit_look_ahead, at most this).
constexpr double kFitHorizon = 1.0;

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
/// - Each interval k between samples k and k+1 has a mean twist m_k = Log(T_k^-1 T_k+1) / h_k, and
///   keeps it: the fitted motion passes through every sample.
/// - The samples from kFitHorizon before the sweep to the one closing it are read and, with a look-ahead
///   L, those up to end + L (at most kFitHorizon): the fit depends on them only, never on what the
///   source holds after them (what arrived later).
/// - The noise is estimated from the samples themselves: how far each interval's mean lies from the
///   best of the simplest local models (constant over two intervals, straight over three, a quartic
///   over six), a median over the window's intervals. Exact samples give a noise of 0 (to a floor of
///   1e-5 m or 1e-6 rad per interval).
/// - With exact samples, each twist component changes over an interval at the slope of a line through
///   it and its neighbours (centred, else on one side: a kink at a sample beside it) where one explains
///   them; at none across a step at a sample between two constant stretches; else, where five intervals
///   around it are smooth (their means' fourth difference within 0.4 of their changes; else no slope),
///   at the slope and curvature of the quartic whose means over the five intervals centred on it are
///   theirs (samples after the sweep: a look-ahead), else of the parabola over three of them that
///   curves least (a smooth twist followed to O(h^3) or O(h^2), the pose one order better; a step or
///   kink beside it: the parabola on its other side).
/// - With noisy samples (noise above 1 % of the component's typical size): each noisy component a
///   cubic smoothing spline through the window's means (smoothNoisy: x'' white noise, its intensity the
///   smoothest within a 95 % likelihood-ratio interval of the most likely); the twist followed as a
///   whole (each interval its own mean, an arc through both samples as tf's line passes through them)
///   where a component changes between samples beyond the noise or the window holds fewer than 30
///   intervals.
/// - Over an interval the fitted twist is integrated to second order (two Magnus terms) such that its
///   end lies where the interval's mean twist takes it.
///
/// Exact for constant linear and angular velocity (an arc; its twist is the same on every interval) and,
/// with exact samples, for a twist that changes linearly or steps at a sample.
class TwistMotion final : public MotionSource {
 public:
  /// Fits the motion of `raw` over [begin, end] from its samples (MotionSource::appendSampleTimes and
  /// basePose at those times), noisy ones also from its samples in (end, end + look_ahead] [ns] that
  /// it answers (DeskewConfig::fit_look_ahead; 0 = none). Returns *this, or `raw` itself when raw
  /// reports no samples at or before `begin` and at or after `end` that it can answer (a continuous
  /// source; tf beyond its newest sample, extrapolated): then its own motion is used as it is. Throws
  /// what raw.basePose throws for a time in [begin, end].
  const MotionSource& prepare(const MotionSource& raw, TimeNs begin, TimeNs end, TimeNs look_ahead = 0);

  /// The fitted pose at `time` within the prepared span's sample intervals; throws MotionUnavailable
  /// elsewhere.
  mrpt::poses::CPose3D basePose(TimeNs time) const override;
  void baseTransform(TimeNs time, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const override;
  /// The sample times in (begin, end): the fitted motion's pieces end there.
  void appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const override;
  TimeNs longestGap(TimeNs begin, TimeNs end) const override;
  /// True when every fitted piece has a constant twist (exact samples of a twist that does not change,
  /// or noisy samples): its pieces are screws.
  bool screwsBetweenSamples() const override { return screws_; }
  bool screwsBetweenKnots() const override { return true; }
  /// A screw between knots d apart strays from a twist changing at rate a by about |a| d^2 / 8: the
  /// spacing at which that stays below 0.02 mm for a point 10 m away on the fastest-changing piece
  /// (0.8 ms at 5 rad/s turning at 1.3 s periods), at least 0.5 ms and at most `requested`.
  double knotInterval(double requested) const override;

  /// The noise [m/s, rad/s] per twist component estimated for the last prepare() (0 when exact or
  /// too few samples).
  const Twist& estimatedNoise() const;

 private:
  struct Sample {
    TimeNs time;
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    Twist mean;  // of the interval to the sample at mean_until (-1: not computed yet)
    TimeNs mean_until;
    /// estimateNoise()'s smallest residual of each kind (step, chord, quartic) of the interval starting
    /// here, per component; a function of the samples from residual_from to residual_to (five intervals
    /// either side), kept with them.
    std::array<Twist, 3> residual{Twist::Zero(), Twist::Zero(), Twist::Zero()};
    TimeNs residual_from = -1, residual_to = -1;
  };
  /// One fitted interval: starts at `time`, lasts `duration` [s]; the twist at t' [s] into it is
  /// start_twist + t' slope; pose there = start pose * Exp(Omega(t')).
  struct Piece {
    TimeNs time;
    double duration;
    Twist start_twist;
    Twist slope;
    Twist curvature = Twist::Zero();  // the twist's second-order term (t'^2), when `curved`
    bool curved = false;
    Eigen::Matrix3d rotation;  // fitted pose at the piece's start
    Eigen::Vector3d translation;
    /// Omega(t') = start t' + slope t'^2 / 2 + t'^3 / 12 [start, slope]: the motion t' [s] into the piece.
    Twist omega(double tau) const;
  };

  /// The index in cache_ of the first cached sample at or after `time`.
  std::size_t cachedAt(TimeNs time) const;
  /// The k-th sample of the window prepare() fits over (kept in cache_).
  Sample& sample(std::size_t k) const { return *samples_[k]; }
  bool gatherSamples(const MotionSource& raw, TimeNs begin, TimeNs end, TimeNs look_ahead);
  void estimateNoise();
  /// Fitted (mean twist, slope) of interval j, component c.
  void fitInterval(std::size_t j, int c, double& mean, double& slope, double& curvature) const;
  /// fitInterval()'s first choice for every exact component of interval j at once (its neighbours'
  /// x sums are common to them): the centred line, where it explains the three means. Sets `fitted`
  /// and the slope there; the others are left as they are (fitInterval() decides).
  void fitCentredLines(std::size_t j, Twist& slope, std::array<bool, 6>& fitted) const;
  /// For each noisy component: the cubic smoothing spline through the window's means, its weight of
  /// the largest likelihood or the smoothest within kLikelihoodMargin of it; kept in smoothed_ for the
  /// sweep's intervals [first, last).
  void smoothNoisy(std::size_t first, std::size_t last);
  /// The filter over component c with the prior's ratio q tau^3 / sigma^2; the log likelihood (sigma^2
  /// at its best). With `keep`, smoothed_[c] for intervals [first, last).
  double smoothComponent(int c, double ratio, std::size_t first, std::size_t last, bool keep);
  std::array<std::vector<Eigen::Vector2d>, 6> smoothed_;  // per component: (twist, rate) at centres
  std::size_t smoothed_first_ = 0;
  double typical_ = 0.0;                        // [s] the window's median interval (estimateNoise())
  std::array<double, 6> diffuse_scale_{};       // smoothComponent()'s prior size, per component
  Twist chosen_ratio_ = Twist::Zero();          // the ratios chosen in the last prepare()
  bool followed_ = false;                       // the noisy twist followed (each interval its mean)
  double innovation_square_ = 0.0;     // smoothComponent()'s mean squared standardised innovation
  std::vector<double> standardised_;  // and its standardised innovations
  std::vector<std::pair<Eigen::Vector2d, Eigen::Matrix2d>> filtered_, predicted_;  // scratch
  std::vector<std::pair<double, double>> likelihoods_;                            // scratch: (ratio, log L)

  const MotionSource* raw_ = nullptr;
  std::vector<Sample*> samples_;  // the window's samples, in cache_ (stable until the next prepare())
  std::size_t closing_ = 0;       // samples_[closing_] closes the sweep; later ones: the look-ahead's
  std::vector<Sample> cache_;     // from cache_start_ on: the source's answers at its sample times, sorted
  std::size_t cache_start_ = 0;   // cache_[0, cache_start_): forgotten, dropped once they outgrow the rest
  const MotionSource* cache_source_ = nullptr;
  TimeNs cache_begin_ = 0;
  std::vector<TimeNs> times_;      // scratch: sample times
  std::vector<Twist> means_;       // per interval
  std::vector<double> durations_;  // [s] per interval
  std::vector<double> centres_;    // [s] interval mid times from the first sample
  mutable Twist noise_ = Twist::Zero();
  /// Components found exact by the quartics' residuals without their median: noise_ is computed from
  /// quartic_residuals_ (their `quartic_middle_`-th smallest) when estimatedNoise() asks.
  mutable std::array<bool, 6> noise_pending_{};
  std::vector<Twist> quartic_residuals_;
  std::size_t quartic_middle_ = 0;
  Twist floor_ = Twist::Zero();
  std::array<bool, 6> noisy_{};  // per component: samples followed, slopes not fitted
  std::vector<Piece> pieces_;
  mutable std::size_t piece_hint_ = 0;  // baseTransform(): the piece of the last time asked
  Eigen::Matrix3d end_rotation_;  // fitted pose at end_time_, the last piece's end
  Eigen::Vector3d end_translation_;
  TimeNs end_time_ = 0;
  double fastest_change_ = 0.0;  // [m/s^2] largest |slope| of a piece, its angular part times 10 m
  bool screws_ = false;
  std::vector<double> scratch_;  // estimateNoise()'s buffer for medians
  /// estimateNoise()'s last medians, its first pivots (any value gives the same medians): of the
  /// intervals' durations, of the smallest residuals per kind and component (kind * 6 + c), of the
  /// means' magnitudes per component.
  double typical_guess_ = 0.0;
  std::array<double, 18> residual_guesses_{};
  std::array<double, 6> size_guesses_{};
  /// estimateNoise()'s largest quartic residual per component that passes as exact, and whether those
  /// tell it, for the floor threshold_floor_ (NaN: none yet).
  std::array<double, 6> thresholds_{};
  bool by_threshold_ = false;
  Twist threshold_floor_ = Twist::Constant(NAN);
  std::vector<Twist> step_, chord_, curve_;  // estimateNoise()'s residuals per stencil
  std::vector<TimeNs> doubled_centres_;       // estimateNoise()'s interval mid times [ns] times two
};

}  // namespace lidar_deskew::core
