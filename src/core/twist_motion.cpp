#include "lidar_deskew/core/twist_motion.h"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>

#include "kth_smallest.h"
#include "pose_eigen.h"

namespace lidar_deskew::core {
namespace {

using detail::kthSmallest;

/// Fewer intervals with a full set of neighbours than this: no noise estimate (samples followed).
constexpr std::size_t kMinNoiseIntervals = 8;
/// Medians over intervals of each kind of simple model's smallest standardised residual (estimateNoise
/// below: a step beside the interval, two of them; a chord, three; a quartic, six), for Gaussian noise
/// of standard deviation 1 (3e6 normal draws).
constexpr double kResidualMedians[3] = {0.3878, 0.2759, 0.1487};
/// The least of the three kinds' estimates, under that noise: 0.84 of it at 100 scored intervals (a 2 s
/// window at 50 Hz; 0.74 at 26, 0.88 at 200; 3000 draws each).
constexpr double kLeastOfKinds = 0.84;
/// ... and at worst (the shortest windows smoothed): 0.74.
constexpr double kLeastOfKindsAtWorst = 0.74;
/// Twist differences below these over an interval move a point by less than 0.01 mm (1e-6 rad at
/// 10 m): counted as exact.
constexpr double kFloorDisplacement = 1e-5;  // [m]
constexpr double kFloorAngle = 1e-6;         // [rad]
/// knotInterval(): screws between knots may stray this far [m] from the fitted motion at this distance
/// [m] from the base, with knots at least kMinKnotSpacing [s] apart.
constexpr double kKnotTolerance = 2e-5;
constexpr double kKnotReach = 10.0;
constexpr double kMinKnotSpacing = 5e-4;
/// Samples whose estimated noise is below this share of a component's typical size are fitted as exact:
/// what the simple models of estimateNoise leave there is the motion's own curvature (1e-4 rad/s on
/// the 5 rad/s smooth drive at 40 Hz), and a parabola's slope through noise that small costs far less
/// than it gains. Odometry with 10 % noise per step is followed.
constexpr double kNoiseShare = 0.01;
/// Nor noise below this many floors (0.1 mm over a typical interval): smoothing it gains nothing a
/// point would show, and its component's ratio, estimated from residuals that small, would decide
/// whether the whole twist is followed (the lateral speed of an arc: UTM-30LX/normal/arc at 10 %).
constexpr double kNoisyFloor = 10.0;
/// fitInterval(): a parabola's slope is trusted where the fourth (or third) difference of five (four)
/// consecutive intervals' means is within this share of the sum of their changes.
constexpr double kSmoothness = 0.4;
/// smoothNoisy(): the smoothness prior's intensity q [(twist/s^2)^2 s] is chosen among ratios
/// rho = q tau^3 / sigma^2 (tau: the typical interval) from kMinRatio to kMaxRatio, kRatioStep apart. Of
/// those, the smoothest one whose log likelihood is within kLikelihoodMargin of the best (2 log L within
/// 3.84: the 95 % interval of a likelihood-ratio test): where the data cannot tell, the smoother model.
constexpr double kMinRatio = 1e-9;
constexpr double kMaxRatio = 1e3;
constexpr double kRatioStep = 3.1622776601683795;  // half a decade
constexpr double kLikelihoodMargin = 1.92;
/// A ratio this large or larger: the twist changes by more than the noise between samples (steps, kinks
/// at samples: 100 on ILD26TRI/varying at 10 % noise, against 0.03-0.1 on the smooth drives and 1e-9
/// on arcs). A spline through them would carry slopes the motion does not have, and smoothing gains
/// little: each interval's twist is then its own mean (an arc through both samples, as tf's line
/// passes through them).
constexpr double kFollowRatio = 1.0;
/// Fewer intervals than this in the window: the samples followed. The noise estimate then rests on
/// fewer than 20 residuals (a median of that few is off by 30 % or more), and a twist stepping at
/// samples can pass for noise (ILD26TRI/varying's first sweeps: 2.7 rad/s estimated, 0.4 true).
constexpr std::size_t kMinSmoothIntervals = 30;
/// The first intervals' state is unknown: this many times the largest mean's variance before them (a
/// diffuse prior), and their innovations are left out of the likelihood.
constexpr double kDiffuse = 1e8;
constexpr std::size_t kDiffuseIntervals = 2;
/// smoothNoisy(): the chosen spline's standardised innovations must be white at lags 2-4: the
/// Ljung-Box statistic below the chi-square quantile (3 degrees of freedom) of 1 - 1e-6, as each sweep
/// tests its window (thousands per recording). Lag 1 is left out: jittered stamps make it -0.5.
constexpr int kFirstLag = 2, kLastLag = 4;
constexpr double kWhitenessLimit = 30.66;
/// Standard normal quantile of the line test (one-sided 99.9 %).
constexpr double kTestQuantile = 3.09;

/// sin(t)/t, (1-cos t)/t^2, (t-sin t)/t^3 for t = |phi|, with series near 0.
void expCoefficients(double angle, double& a, double& b, double& c) {
  const double t2 = angle * angle;
  if (t2 < 1e-6) {
    a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0);
    b = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0);
    c = 1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0);
  } else {
    a = std::sin(angle) / angle;
    b = (1.0 - std::cos(angle)) / t2;
    c = (angle - std::sin(angle)) / (t2 * angle);
  }
}

/// Chi-square quantile for `dof` degrees of freedom at kTestQuantile (Wilson-Hilferty).
double lineTestLimit(double dof) {
  const double k = 2.0 / (9.0 * dof);
  const double root = 1.0 - k + kTestQuantile * std::sqrt(k);
  return dof * root * root * root;
}

/// The Ljung-Box statistic of `values` over lags kFirstLag..kLastLag: n (n + 2) sum r_k^2 / (n - k),
/// r_k the autocorrelation at lag k (chi-square with kLastLag - kFirstLag + 1 degrees of freedom for
/// white values).
double ljungBox(const std::vector<double>& values) {
  const std::size_t n = values.size();
  if (n <= static_cast<std::size_t>(kLastLag) + 1)
    return 0.0;
  double mean = 0.0;
  for (const double value : values)
    mean += value;
  mean /= static_cast<double>(n);
  double variance = 0.0;
  for (const double value : values)
    variance += (value - mean) * (value - mean);
  if (!(variance > 0.0))
    return 0.0;
  double sum = 0.0;
  for (int lag = kFirstLag; lag <= kLastLag; ++lag) {
    const std::size_t l = static_cast<std::size_t>(lag);
    double covariance = 0.0;
    for (std::size_t k = l; k < n; ++k)
      covariance += (values[k] - mean) * (values[k - l] - mean);
    const double r = covariance / variance;
    sum += r * r / static_cast<double>(n - l);
  }
  return static_cast<double>(n) * static_cast<double>(n + 2) * sum;
}

/// Least-squares line y = alpha + beta x over running sums; residual sum of squares.
struct LineSums {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  void add(double x, double y) {
    n += 1;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    syy += y * y;
  }
  /// False when the x do not span a line (fewer than two distinct values).
  bool fit(double& alpha, double& beta, double& rss) const {
    const double det = n * sxx - sx * sx;
    if (!(det > 1e-30 * n * sxx))
      return false;
    beta = (n * sxy - sx * sy) / det;
    alpha = (sy - beta * sx) / n;
    rss = std::max(0.0, syy - alpha * sy - beta * sxy);
    return true;
  }
};

/// True when an entry of v is -0 (x + (+/-0) is x for every other x).
bool hasNegativeZero(const Eigen::Vector3d& v) {
  return (v.x() == 0.0 && std::signbit(v.x())) || (v.y() == 0.0 && std::signbit(v.y())) ||
         (v.z() == 0.0 && std::signbit(v.z()));
}

/// se3Bracket(), here where the fit calls it in its loops.
inline Twist bracket(const Twist& a, const Twist& b) {
  Twist out;
  out.head<3>() = a.tail<3>().cross(b.head<3>()) - b.tail<3>().cross(a.head<3>());
  out.tail<3>() = a.tail<3>().cross(b.tail<3>());
  return out;
}

}  // namespace

void se3Exp(const Twist& xi, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  double a, b, c;
  expCoefficients(phi.norm(), a, b, c);
  const Eigen::Matrix3d k = detail::skew(phi);
  const Eigen::Matrix3d k2 = k * k;
  rotation = Eigen::Matrix3d::Identity() + a * k + b * k2;
  translation = rho + b * (k * rho) + c * (k2 * rho);
}

Twist se3Log(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  double angle;
  Eigen::Vector3d phi;
  if (rotation(0, 2) == 0.0 && rotation(1, 2) == 0.0 && rotation(2, 0) == 0.0 && rotation(2, 1) == 0.0 &&
      rotation(2, 2) == 1.0) {
    // A turn about z only (planar odometry, exactly): its angle from the matrix directly.
    const double yaw = std::atan2(rotation(1, 0) - rotation(0, 1), rotation(0, 0) + rotation(1, 1));
    angle = std::abs(yaw);
    phi = Eigen::Vector3d(0.0, 0.0, yaw);
  } else {
    const Eigen::AngleAxisd angle_axis(rotation);
    angle = angle_axis.angle();
    phi = angle * angle_axis.axis();
  }
  // V^-1 = I - K/2 + d K^2, d = (1 - a / (2 b)) / t^2 (-> 1/12 at 0)
  double a, b, c;
  expCoefficients(angle, a, b, c);
  const double t2 = angle * angle;
  const double d = t2 < 1e-6 ? 1.0 / 12.0 + t2 / 720.0 : (1.0 - a / (2.0 * b)) / t2;
  const Eigen::Matrix3d k = detail::skew(phi);
  Twist xi;
  xi.head<3>() = translation - 0.5 * (k * translation) + d * (k * (k * translation));
  xi.tail<3>() = phi;
  return xi;
}

Twist se3Bracket(const Twist& a, const Twist& b) { return bracket(a, b); }

Twist TwistMotion::Piece::omega(double tau) const {
  const double tau3 = tau * tau * tau;
  Twist result = start_twist * tau + slope * (0.5 * tau * tau) + (tau3 / 12.0) * bracket(start_twist, slope);
  if (curved)
    result += curvature * (tau3 / 3.0) + (tau3 * tau / 12.0) * bracket(start_twist, curvature) +
              (tau3 * tau * tau / 60.0) * bracket(slope, curvature);
  return result;
}

std::size_t TwistMotion::cachedAt(TimeNs time) const {
  return static_cast<std::size_t>(
      std::lower_bound(cache_.begin() + static_cast<std::ptrdiff_t>(cache_start_), cache_.end(), time,
                       [](const Sample& sample, TimeNs t) { return sample.time < t; }) -
      cache_.begin());
}

bool TwistMotion::gatherSamples(const MotionSource& raw, TimeNs begin, TimeNs end, TimeNs look_ahead) {
  times_.clear();
  // appendSampleTimes gives times strictly inside; the margins include the samples bracketing the sweep.
  const TimeNs horizon = secondsToNs(kFitHorizon);
  look_ahead = std::min(look_ahead, horizon);
  raw.appendSampleTimes(begin - horizon - 1, end + std::max(horizon, look_ahead) + 1, times_);
  // Sources report their times in order (tf, PoseSamples): one pass then finds them increasing, else
  // they are sorted and repeated times dropped.
  if (std::adjacent_find(times_.begin(), times_.end(), std::greater_equal<TimeNs>()) != times_.end()) {
    std::sort(times_.begin(), times_.end());
    times_.erase(std::unique(times_.begin(), times_.end()), times_.end());
  }
  const auto after_begin = std::upper_bound(times_.begin(), times_.end(), begin);
  const auto at_end = std::lower_bound(times_.begin(), times_.end(), end);
  if (after_begin == times_.begin() || at_end == times_.end())
    return false;
  // After the sweep only the sample that closes it and those up to end + look_ahead: the fit then
  // depends on nothing after them, so how much tf had arrived by the time the sweep is corrected
  // cannot change its correction once tf covers that time.
  auto kept_end = at_end + 1;
  if (look_ahead > 0)
    kept_end = std::max(kept_end, std::upper_bound(times_.begin(), times_.end(), end + look_ahead));
  times_.erase(kept_end, times_.end());
  const std::size_t first = static_cast<std::size_t>(after_begin - times_.begin()) - 1;
  const std::size_t last = static_cast<std::size_t>(at_end - times_.begin());

  // The source's answer at a sample time does not change once given: answers are kept for the next
  // sweeps (which share most of their window), until time goes back (a bag loop, a clock reset).
  if (begin < cache_begin_ || &raw != cache_source_) {
    cache_.clear();
    cache_start_ = 0;
  }
  cache_begin_ = begin;
  cache_source_ = &raw;
  // The queries walk outwards from the sweep's first sample, and the cache along with them by index
  // (most times are cached: only the new ones are asked and inserted where they sort). The cache's
  // samples are cache_[cache_start_, size): one inserted at its front takes the slot before it when
  // there is one. `position` is where it sorts; returns false when the source does not answer, else
  // sets `position` to where it was put.
  const auto ask = [&](std::size_t i, std::size_t& position) {
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    try {
      raw.baseTransform(times_[i], rotation, translation);
    } catch (const MotionUnavailable&) {
      return false;
    }
    if (position == cache_start_ && cache_start_ > 0) {
      position = --cache_start_;
    } else if (position == cache_.size()) {
      cache_.emplace_back();
    } else {
      cache_.insert(cache_.begin() + static_cast<std::ptrdiff_t>(position), cache_[position]);
    }
    // Written in place; nothing computed from it yet (its residuals are read only once computed).
    Sample& answer = cache_[position];
    answer.time = times_[i];
    answer.rotation = rotation;
    answer.translation = translation;
    answer.mean.setZero();
    answer.mean_until = -1;
    answer.residual_from = answer.residual_to = -1;
    return true;
  };
  // From the sweep's first sample outwards, stopping where the source no longer answers (a chain's
  // links end at different times): times_[low, high) are answered. `cached`: the cache's samples from
  // there on are at or after the last time answered (before it going down, after it going up).
  std::size_t cached = cachedAt(times_[first]);
  while (cached < cache_.size() && cache_[cached].time == times_[first])
    ++cached;  // just after times_[first] when it is cached
  std::size_t low = first + 1;
  // Most of them are cached one after the other: the walk's steps that find so, in one pass; then the rest.
  while (low > 0 && cached > cache_start_ && cache_[cached - 1].time == times_[low - 1]) {
    --cached;
    --low;
  }
  while (low > 0) {
    const TimeNs time = times_[low - 1];
    while (cached > cache_start_ && cache_[cached - 1].time > time)
      --cached;  // no longer a sample time of the source (skipped, as before)
    if (cached > cache_start_ && cache_[cached - 1].time == time) {
      --cached;
    } else if (!ask(low - 1, cached)) {
      if (low - 1 == first)
        return false;
      break;
    }
    --low;
  }
  cached = cachedAt(times_[first] + 1);
  std::size_t high = first + 1;
  while (high < times_.size()) {
    const TimeNs time = times_[high];
    while (cached < cache_.size() && cache_[cached].time < time)
      ++cached;
    if (cached < cache_.size() && cache_[cached].time == time) {
      ++cached;
    } else if (ask(high, cached)) {
      ++cached;
    } else {
      if (high <= last)
        return false;
      break;
    }
    ++high;
  }
  // Forget what no later sweep's window reaches (by moving the cache's start; its dead front is dropped
  // once it outgrows the live samples), then point at the window's samples in the cache (no more
  // insertions until the next prepare(): the pointers stay valid).
  cache_start_ = cachedAt(times_[low]);
  if (cache_start_ > 0 && cache_start_ >= cache_.size() - cache_start_) {
    cache_.erase(cache_.begin(), cache_.begin() + static_cast<std::ptrdiff_t>(cache_start_));
    cache_start_ = 0;
  }
  samples_.resize(high - low);
  std::size_t kept = cache_start_;
  for (std::size_t i = low; i < high; ++i) {
    while (cache_[kept].time < times_[i])
      ++kept;
    samples_[i - low] = &cache_[kept++];  // the next time is later
  }
  closing_ = last - low;
  return samples_.size() >= 2;
}

const Twist& TwistMotion::estimatedNoise() const {
  for (std::size_t c = 0; c < 6; ++c) {
    if (!noise_pending_[c])
      continue;
    // As estimateNoise() computes it for the quartics: the least of kinds is theirs.
    const auto residual = [this, c](std::size_t j) { return quartic_residuals_[j][static_cast<int>(c)]; };
    std::vector<double> buffer;
    double guess = NAN;
    const double least = std::min(
        static_cast<double>(INFINITY),
        kthSmallest(quartic_residuals_.size(), quartic_middle_, residual, buffer, guess) / kResidualMedians[2]);
    noise_[static_cast<int>(c)] = least / kLeastOfKinds;
    noise_pending_[c] = false;
  }
  return noise_;
}

void TwistMotion::estimateNoise() {
  const std::size_t count = means_.size();
  noise_.setZero();
  noise_pending_.fill(false);
  // The floor: twist differences that move a point by less than 0.01 mm over a typical interval.
  const auto duration = [this](std::size_t k) { return durations_[k]; };
  typical_ = kthSmallest(count, count / 2, duration, scratch_, typical_guess_);
  floor_.head<3>().setConstant(kFloorDisplacement / typical_);
  floor_.tail<3>().setConstant(kFloorAngle / typical_);
  noisy_.fill(false);
  if (count < kMinNoiseIntervals + 10)
    return;
  // Each interval's mean against the best of the simplest local models that can hold it: constant over
  // it and one neighbour, a line through three, a quartic through six (any stencil containing it); each
  // residual divided by its standard deviation under unit noise. Steps, kinks and smooth curves of the
  // true twist leave one of them exact or nearly; noise leaves all of them off. The residuals of each
  // stencil are computed once, for all six components.
  // step_[k]: |m_k+1 - m_k| / sqrt(2); chord_[k]: m_k from the line through k-1 and k+1; curve_[i]: m_i+5
  // from the quartic through i..i+4 (Lagrange extrapolation: a smooth curve's twist, rough ground at
  // 2-3 Hz, is explained by it to 0.2 % of its amplitude at 50 Hz).
  // Interval j's smallest residual (j in [5, count - 6], the ones scored) reads the samples j-5 to j+6
  // only, and only through their poses and the differences of their times, which are exact in integer
  // nanoseconds: it does not depend on the window and is kept with sample j for later sweeps. Only the
  // intervals from the first one not kept are computed (a new sweep: its own), and the stencils they read.
  const auto keptFor = [&](std::size_t j) {
    const Sample& kept = sample(j);
    return kept.residual_from == sample(j - 5).time && kept.residual_to == sample(j + 6).time;
  };
  std::size_t fresh = 5;
  while (fresh + 6 <= count && keptFor(fresh))
    ++fresh;
  if (fresh + 6 <= count) {
    // Twice the intervals' mid times [ns]: their differences are exact. Those the stencils below read.
    doubled_centres_.resize(count);
    for (std::size_t k = fresh - 5; k < count; ++k)
      doubled_centres_[k] = sample(k).time + sample(k + 1).time;
    const auto apart = [&](std::size_t a, std::size_t b) {
      return static_cast<double>(doubled_centres_[a] - doubled_centres_[b]);
    };
    step_.resize(count);
    chord_.resize(count);
    curve_.resize(count);
    for (std::size_t k = fresh - 1; k + 6 <= count; ++k)
      step_[k] = (means_[k + 1] - means_[k]).cwiseAbs() / std::sqrt(2.0);
    for (std::size_t k = fresh - 1; k + 5 <= count; ++k) {
      const double w_before = apart(k + 1, k) / apart(k + 1, k - 1);
      const double w_after = 1.0 - w_before;
      chord_[k] = (means_[k] - w_before * means_[k - 1] - w_after * means_[k + 1]).cwiseAbs() /
                  std::sqrt(1.0 + w_before * w_before + w_after * w_after);
    }
    for (std::size_t i = fresh - 5; i + 5 < count; ++i) {
      // Point a's weight is the product over b != a of (centre_5 - centre_b) / (centre_a - centre_b), in
      // increasing b (the order fixes its rounding). The twenty quotients do not depend on each other:
      // divided as one array, two at a time. Their denominators are ten differences and their negations
      // (centre_b - centre_a, exactly: the integer difference negated, rounded the same; never 0, the
      // centres increase).
      double to_last[5];
      for (std::size_t a = 0; a < 5; ++a)
        to_last[a] = apart(i + 5, i + a);
      // Point a's quotients are 4 a to 4 a + 3, with b = 0 .. 4 but a, increasing: b's at 4 a + b - 1
      // for b > a, at 4 a + b for b < a (d_ab: centre_a - centre_b).
      const double d01 = apart(i, i + 1), d02 = apart(i, i + 2), d03 = apart(i, i + 3), d04 = apart(i, i + 4);
      const double d12 = apart(i + 1, i + 2), d13 = apart(i + 1, i + 3), d14 = apart(i + 1, i + 4);
      const double d23 = apart(i + 2, i + 3), d24 = apart(i + 2, i + 4), d34 = apart(i + 3, i + 4);
      const double* const l = to_last;
      alignas(16) const double numerators[20] = {l[1], l[2], l[3], l[4], l[0], l[2], l[3], l[4], l[0], l[1],
                                                 l[3], l[4], l[0], l[1], l[2], l[4], l[0], l[1], l[2], l[3]};
      alignas(16) const double denominators[20] = {d01,  d02,  d03,  d04,  -d01, d12,  d13,
                                                   d14,  -d02, -d12, d23,  d24,  -d03, -d13,
                                                   -d23, d34,  -d04, -d14, -d24, -d34};
      const Eigen::Array<double, 20, 1> quotients = Eigen::Map<const Eigen::Array<double, 20, 1>, Eigen::Aligned16>(numerators) /
                                                    Eigen::Map<const Eigen::Array<double, 20, 1>, Eigen::Aligned16>(denominators);
      Twist prediction = Twist::Zero();
      double variance = 1.0;
      for (int a = 0; a < 5; ++a) {
        const double weight =
            quotients[4 * a] * quotients[4 * a + 1] * quotients[4 * a + 2] * quotients[4 * a + 3];
        prediction += weight * means_[i + static_cast<std::size_t>(a)];
        variance += weight * weight;
      }
      curve_[i] = (means_[i + 5] - prediction).cwiseAbs() / std::sqrt(variance);
    }
    // Each interval's smallest residual of each kind, all six components at once (cwiseMin is
    // std::min, element by element).
    for (std::size_t j = fresh; j + 6 <= count; ++j) {
      Sample& kept = sample(j);
      kept.residual[0] = step_[j - 1].cwiseMin(step_[j]);
      kept.residual[1] = chord_[j - 1].cwiseMin(chord_[j]).cwiseMin(chord_[j + 1]);
      Twist e = curve_[j - 5];
      for (std::size_t i = j - 4; i <= j; ++i)
        e = e.cwiseMin(curve_[i]);
      kept.residual[2] = e;
      kept.residual_from = sample(j - 5).time;
      kept.residual_to = sample(j + 6).time;
    }
  }
  // Each kind's estimate is the median of its smallest residuals (per component, read from the scored
  // samples as the median takes them), and the noise the least of the three. A kind that holds the true
  // twist on most intervals gives the noise; one that does not gives more (a turn rate stepping every
  // other sample holds only the steps, with quantised or jittered samples). Taking the least errs towards
  // less noise, which smooths less: towards tf's line. (The smallest of all eleven residuals, one median,
  // took a stepping turn rate for noise 8 times its own: only one of the eleven held it.)
  const std::size_t scored = count - 10;
  const std::size_t middle = scored / 2;
  // Quartics first, which hold a smooth motion: once a kind puts the noise below what is smoothed
  // (kNoisyFloor floors), the component is exact whatever the others say, and they are not computed.
  // Whether the quartics' median does so is known without it: the estimate and the noise from it
  // never decrease with the value they come from, so the median passes both tests exactly when more
  // than `middle` of the values do (counted for all components at once). Its value is then only
  // reported (estimatedNoise()): the values are kept, and their median taken when asked.
  // The tests, on a residual v: passes(v). The largest value passing, found from a guess by a few
  // steps of one ulp, then tells them by one comparison (any value may be NaN: it passes neither).
  // They depend on the floor only, which most sweeps share with the last (the same typical interval):
  // then the last sweep's are used.
  if (!(floor_.array() == threshold_floor_.array()).all()) {
    threshold_floor_ = floor_;
    by_threshold_ = true;
    for (int c = 0; c < 6; ++c) {
      const double noisy_floor = kNoisyFloor * floor_[c];
      const double exact_least = noisy_floor * kLeastOfKinds;
      const auto passes = [&](double v) {
        const double least = v / kResidualMedians[2];
        return least <= exact_least && least / kLeastOfKinds <= noisy_floor;
      };
      if (!(exact_least >= 0.0 && noisy_floor >= 0.0 && std::isfinite(noisy_floor) &&
            std::isfinite(exact_least))) {
        by_threshold_ = false;
        break;
      }
      // passes(0) holds, and passes(v) never turns true again once false as v grows.
      double v = std::min(exact_least, noisy_floor * kLeastOfKinds) * kResidualMedians[2];
      int steps = 0;
      for (; steps < 64 && v < INFINITY && passes(v); ++steps)
        v = std::nextafter(v, INFINITY);
      for (; steps < 128 && !passes(v); ++steps)
        v = std::nextafter(v, -INFINITY);
      by_threshold_ = by_threshold_ && steps < 128 && passes(v) &&
                      (v == INFINITY || !passes(std::nextafter(v, INFINITY)));
      thresholds_[static_cast<std::size_t>(c)] = v;
    }
  }
  const bool by_threshold = by_threshold_;
  const double* const threshold = thresholds_.data();
  std::size_t passing[6] = {};
  quartic_residuals_.resize(scored);
  for (std::size_t j = 0; j < scored; ++j) {
    const Twist& residual = sample(j + 5).residual[2];
    quartic_residuals_[j] = residual;
    if (by_threshold) {
      for (int c = 0; c < 6; ++c)
        passing[c] += residual[c] <= threshold[c] ? 1 : 0;
    }
  }
  if (!by_threshold) {
    std::fill(std::begin(passing), std::end(passing), 0);  // none told exact here: the medians decide
  }
  quartic_middle_ = middle;
  for (std::size_t c = 0; c < 6; ++c) {
    if (passing[c] > middle) {
      noise_pending_[c] = true;  // exact; noise_ from quartic_residuals_ when asked
      continue;
    }
    const double exact_below = kNoisyFloor * floor_[static_cast<int>(c)] * kLeastOfKinds;
    double least = INFINITY;
    for (std::size_t kind = 3; kind-- > 0 && !(least <= exact_below);) {
      const auto residual = [&, kind, c](std::size_t j) {
        return sample(j + 5).residual[kind][static_cast<int>(c)];
      };
      least =
          std::min(least, kthSmallest(scored, middle, residual, scratch_, residual_guesses_[kind * 6 + c]) /
                              kResidualMedians[kind]);
    }
    noise_[static_cast<int>(c)] = least / kLeastOfKinds;
  }
  // Noisy: above the floor and above kNoiseShare of the component's typical size (the median of its
  // means' magnitudes). Below, what the simple models leave is taken for the motion's own curvature.
  for (std::size_t c = 0; c < 6; ++c) {
    if (noise_pending_[c] || !(noise_[static_cast<int>(c)] > kNoisyFloor * floor_[static_cast<int>(c)]))
      continue;  // exact: its typical size is not needed
    const auto magnitude = [&, c](std::size_t k) { return std::abs(means_[k][static_cast<int>(c)]); };
    const double typical_size = kthSmallest(count, count / 2, magnitude, scratch_, size_guesses_[c]);
    noisy_[c] = noise_[static_cast<int>(c)] > std::max(kNoisyFloor * floor_[static_cast<int>(c)], kNoiseShare * typical_size);
  }
}

void TwistMotion::fitCentredLines(std::size_t j, Twist& slope, std::array<bool, 6>& fitted) const {
  if (j == 0 || j + 1 >= means_.size())
    return;
  // fitInterval's sums, in its order: the x ones shared by the components.
  const double x[3] = {centres_[j - 1] - centres_[j], centres_[j] - centres_[j], centres_[j + 1] - centres_[j]};
  LineSums shared;
  for (const double value : x)
    shared.add(value, 0.0);
  const double n = shared.n, sx = shared.sx, sxx = shared.sxx;
  const double det = n * sxx - sx * sx;
  if (!(det > 1e-30 * n * sxx))
    return;
  const double limit = lineTestLimit(1.0);
  // The six components at once, each lane in the scalar sums' order (the same roundings).
  using Lanes = Eigen::Array<double, 6, 1>;
  const Lanes y0 = means_[j - 1].array(), y1 = means_[j].array(), y2 = means_[j + 1].array();
  Lanes sy = Lanes::Zero(), sxy = Lanes::Zero(), syy = Lanes::Zero();
  sy += y0;
  sxy += x[0] * y0;
  syy += y0 * y0;
  sy += y1;
  sxy += x[1] * y1;
  syy += y1 * y1;
  sy += y2;
  sxy += x[2] * y2;
  syy += y2 * y2;
  const Lanes beta = (n * sxy - sx * sy) / det;
  const Lanes alpha = (sy - beta * sx) / n;
  const Lanes unclamped = syy - alpha * sy - beta * sxy;
  // std::max(0.0, v): v where 0 < v, else 0 (NaN too).
  const Lanes rss = (unclamped > 0.0).select(unclamped, Lanes::Zero());
  const Lanes bound = floor_.array() * floor_.array() * limit;
  for (int c = 0; c < 6; ++c) {
    if (!noisy_[static_cast<std::size_t>(c)] && rss[c] <= bound[c] && rss[c] < INFINITY) {
      slope[c] = beta[c];
      fitted[static_cast<std::size_t>(c)] = true;
    }
  }
}

void TwistMotion::fitInterval(std::size_t j, int c, double& mean, double& slope, double& curvature) const {
  const std::size_t count = means_.size();
  const double variance = floor_[c] * floor_[c];
  const auto x = [&](std::size_t k) { return centres_[k] - centres_[j]; };
  const auto y = [&](std::size_t k) { return means_[k][c]; };
  // Exact samples: the interval keeps its own mean, so that the fitted motion passes through every
  // sample (means off by up to the floor would add up along the sweep's pieces); only the slope is
  // fitted.
  mean = y(j);
  slope = 0.0;
  curvature = 0.0;
  // Noisy samples: the smoother's twist at the interval's centre and its rate of change there
  // (smoothNoisy).
  if (noisy_[static_cast<std::size_t>(c)]) {
    if (followed_)
      return;
    const Eigen::Vector2d& state = smoothed_[static_cast<std::size_t>(c)][j - smoothed_first_];
    mean = state[0];
    slope = state[1];
    return;
  }
  // A line through three intervals around it, centred first, else on one side (a kink at a sample
  // beside it): the twist changing linearly or constant.
  double best_rss = INFINITY;
  for (const long offset : {-1L, -2L, 0L}) {
    const long start = static_cast<long>(j) + offset;
    if (start < 0 || start + 2 >= static_cast<long>(count))
      continue;
    LineSums three;
    for (long k = start; k < start + 3; ++k)
      three.add(x(static_cast<std::size_t>(k)), y(static_cast<std::size_t>(k)));
    double alpha, beta, rss;
    if (three.fit(alpha, beta, rss) && rss <= variance * lineTestLimit(1.0) && rss < best_rss) {
      best_rss = rss;
      slope = beta;
      if (offset == -1)
        break;  // the centred line explains it
    }
  }
  if (best_rss < INFINITY)
    return;
  // A step at a sample between two constant stretches (a turn rate flipping every other sample): the
  // interval's twist equals its neighbour's on one side, and the other side's two neighbours equal each
  // other but not it. Its own constant twist then. (Equal on one side only is not enough: the two
  // intervals either side of a smooth twist's extremum have equal means too.)
  if (j > 0 && j + 1 < count) {
    const double step_limit = 2.0 * variance * lineTestLimit(1.0);
    const auto same = [&](std::size_t a, std::size_t b) { return (y(a) - y(b)) * (y(a) - y(b)) <= step_limit; };
    const bool same_before = same(j - 1, j), same_after = same(j + 1, j);
    if (same_before != same_after) {
      const bool flat_beyond = same_before ? j + 2 < count && same(j + 1, j + 2) : j >= 2 && same(j - 1, j - 2);
      if (flat_beyond)
        return;
    }
  }
  // The twist curves here beyond the noise: the interval's own mean, changing at the slope of a
  // parabola through it and two neighbouring intervals. A smooth twist is then followed to O(h^2) and
  // the pose to O(h^3) between the samples, which stay exact.
  // The parabola whose means over intervals lo, lo+1, lo+2 are theirs: q(x) = a + b x + q x^2 about
  // interval j's centre, whose mean over interval k (centre x_k, length h_k) is
  // a + b x_k + q (x_k^2 + h_k^2 / 12). Returns (b, q).
  const auto parabola = [&](std::size_t lo) {
    Eigen::Matrix3d averages;
    Eigen::Vector3d values;
    for (int r = 0; r < 3; ++r) {
      const std::size_t k = lo + static_cast<std::size_t>(r);
      averages.row(r) << 1.0, x(k), x(k) * x(k) + durations_[k] * durations_[k] / 12.0;
      values[r] = y(k);
    }
    const Eigen::Vector3d solution = averages.partialPivLu().solve(values);
    return Eigen::Vector2d(solution[1], solution[2]);
  };
  // The parabola's slope is trusted only where the twist is smooth around the interval: over five
  // consecutive intervals holding it (centred where the samples allow), the fourth difference of their
  // means within 0.4 of the sum of the changes between them. A smooth twist leaves about (omega h)^3 / 4
  // of them (a fiftieth at 10 Hz on the smooth drives' 1.3 s turn); a step leaves at least one, a turn
  // rate flipping every other sample one, a kink a half. Four intervals: the third difference, the same
  // way. Else the slope is 0 (the twist stepped or kinked at a sample; the parabola would carry it).
  if (count < 3)
    return;  // no parabola: the interval's own twist
  const std::size_t span = std::min<std::size_t>(count, 5);
  if (span >= 4) {  // fewer (the first sweeps of a recording): no evidence either way, the parabola
    const std::size_t lo_span = std::min(j >= 2 ? j - 2 : 0, count - span);
    double difference = 0.0, changes = 0.0;
    const double binomial[2][5] = {{1.0, -3.0, 3.0, -1.0, 0.0}, {1.0, -4.0, 6.0, -4.0, 1.0}};
    for (std::size_t r = 0; r < span; ++r) {
      difference += binomial[span - 4][r] * y(lo_span + r);
      if (r > 0)
        changes += std::abs(y(lo_span + r) - y(lo_span + r - 1));
    }
    if (std::abs(difference) > kSmoothness * changes)
      return;
  }
  // At the ends of the samples (the sweep's last interval, whose next sample has not come) only the
  // parabola on one side is there.
  // Five smooth intervals centred on it (tf's samples after the sweep, a look-ahead): the quartic whose
  // means over them are theirs; its slope and curvature at the centre are a smooth twist's to O(h^3)
  // and O(h^2) (a parabola's: O(h^2), O(h)).
  if (span == 5 && j >= 2 && j + 2 < count) {
    Eigen::Matrix<double, 5, 5> averages;
    Eigen::Matrix<double, 5, 1> values;
    for (int r = 0; r < 5; ++r) {
      const std::size_t k = j - 2 + static_cast<std::size_t>(r);
      const double lo_x = x(k) - 0.5 * durations_[k], hi_x = x(k) + 0.5 * durations_[k];
      double lo_power = 1.0, hi_power = 1.0;
      for (int n = 0; n < 5; ++n) {
        lo_power *= lo_x;
        hi_power *= hi_x;
        averages(r, n) = (hi_power - lo_power) / ((n + 1) * durations_[k]);
      }
      values[r] = y(k);
    }
    const Eigen::Matrix<double, 5, 1> solution = averages.partialPivLu().solve(values);
    slope = solution[1];
    curvature = solution[2];
    return;
  }
  if (j == 0 || j + 1 == count) {
    const Eigen::Vector2d fitted = parabola(j == 0 ? 0 : j - 2);
    slope = fitted[0];
    curvature = fitted[1];
    return;
  }
  // Else the three intervals that curve least: a step or kink at a sample beside the interval leaves
  // the parabola on its other side smooth.
  double least_curvature = INFINITY;
  for (std::size_t lo_k = j >= 2 ? j - 2 : 0; lo_k <= j && lo_k + 2 < count; ++lo_k) {
    const Eigen::Vector2d fitted = parabola(lo_k);
    // Ties (a parabola: equal curvatures) go to the centred stencil, which comes second.
    if (std::abs(fitted[1]) < least_curvature * (lo_k + 1 == j ? 1.0 + 1e-9 : 1.0)) {
      least_curvature = std::abs(fitted[1]);
      slope = fitted[0];
      curvature = fitted[1];
    }
  }
}

double TwistMotion::smoothComponent(int c, double ratio, std::size_t first, std::size_t last, bool keep) {
  // A Kalman filter forward over the window's intervals, in units of the noise's variance sigma^2
  // (estimateNoise()'s), and a Rauch-Tung-
  // Striebel pass back over the sweep's intervals when `keep`. State (x, x'): the component and its rate
  // of change at an interval's centre; x'' is white noise of intensity q = ratio sigma^2 / tau^3;
  // interval k's mean measures x at its centre with variance sigma^2 tau / h_k (a sum of h_k / tau
  // independent steps' noise, per unit time).
  const std::size_t count = means_.size();
  const double sigma2 = noise_[c] * noise_[c] + floor_[c] * floor_[c];
  const double q = ratio * sigma2 / (typical_ * typical_ * typical_);
  filtered_.resize(count);
  predicted_.resize(count);
  Eigen::Vector2d m(means_[0][c], 0.0);
  Eigen::Matrix2d p = Eigen::Matrix2d::Zero();
  p(0, 0) = p(1, 1) = kDiffuse * diffuse_scale_[static_cast<std::size_t>(c)] * sigma2;
  double squares = 0.0, log_variances = 0.0;
  standardised_.clear();
  for (std::size_t k = 0; k < count; ++k) {
    if (k > 0) {
      const double dt = centres_[k] - centres_[k - 1];
      // m = F m, P = F P F' + Q with F = [1 dt; 0 1], Q = q [dt^3/3 dt^2/2; dt^2/2 dt].
      m[0] += dt * m[1];
      const double p00 = p(0, 0) + dt * (2.0 * p(0, 1) + dt * p(1, 1)) + q * dt * dt * dt / 3.0;
      const double p01 = p(0, 1) + dt * p(1, 1) + q * dt * dt / 2.0;
      p(0, 0) = p00;
      p(0, 1) = p(1, 0) = p01;
      p(1, 1) += q * dt;
    }
    predicted_[k] = {m, p};
    const double r = sigma2 * typical_ / durations_[k];
    const double s = p(0, 0) + r;
    const double innovation = means_[k][c] - m[0];
    if (k >= kDiffuseIntervals) {
      standardised_.push_back(innovation / std::sqrt(s));
      squares += innovation * innovation / s;
      log_variances += std::log(s);
    }
    const Eigen::Vector2d gain = p.col(0) / s;
    m += gain * innovation;
    p -= gain * p.row(0);
    filtered_[k] = {m, p};
  }
  // The log likelihood, up to a constant (sigma^2 estimated from the samples, estimateNoise(): left free,
  // a twist stepping at samples would pass for noise).
  const double log_likelihood = -0.5 * (squares + log_variances);
  innovation_square_ = squares / static_cast<double>(count - kDiffuseIntervals);
  if (keep) {
    // Back from the window's end to the sweep's first interval: x_k = m_k + G (x_k+1 - m_k+1|k), with
    // G = P_k F' P_k+1|k^-1.
    std::vector<Eigen::Vector2d>& smoothed = smoothed_[static_cast<std::size_t>(c)];
    smoothed.resize(last - first);
    Eigen::Vector2d next = filtered_[count - 1].first;
    for (std::size_t k = count - 1; k-- > first;) {
      const double dt = centres_[k + 1] - centres_[k];
      Eigen::Matrix2d f;
      f << 1.0, dt, 0.0, 1.0;
      const Eigen::Matrix2d gain = filtered_[k].second * f.transpose() * predicted_[k + 1].second.inverse();
      next = filtered_[k].first + gain * (next - predicted_[k + 1].first);
      if (k < last)
        smoothed[k - first] = next;
    }
    if (last == count)
      smoothed[last - 1 - first] = filtered_[count - 1].first;
  }
  return log_likelihood;
}

void TwistMotion::smoothNoisy(std::size_t first, std::size_t last) {
  // Each noisy component is one function of time, the smoothest the window's means allow: a cubic
  // smoothing spline (x'' white noise: the Gaussian-process prior of a twist whose rate of change
  // wanders), its weight chosen by the likelihood of the means (docs/DESIGN.md §5). Where one
  // component's changes exceed the noise, or the window is too short to tell, the twist is followed as
  // a whole: its components are one motion's (smoothing the lateral speed of a robot whose turn rate
  // steps, alone, made ILD26TRI/varying worse than tf's line).
  smoothed_first_ = first;
  followed_ = means_.size() < kMinSmoothIntervals;
  chosen_ratio_.setZero();
  if (followed_)
    return;
  for (std::size_t c = 0; c < 6 && !followed_; ++c) {
    if (!noisy_[c])
      continue;
    const int component = static_cast<int>(c);
    double largest = 0.0;
    for (const Twist& mean : means_)
      largest = std::max(largest, std::abs(mean[component]));
    // The diffuse prior: large against the means' own scale.
    const double sigma2 = noise_[component] * noise_[component] + floor_[component] * floor_[component];
    diffuse_scale_[c] = (largest * largest + sigma2) / sigma2;
    likelihoods_.clear();
    for (double ratio = kMinRatio; ratio <= kMaxRatio * 1.0001; ratio *= kRatioStep)
      likelihoods_.emplace_back(ratio, smoothComponent(component, ratio, first, last, false));
    double best = -INFINITY;
    for (const auto& [ratio, likelihood] : likelihoods_)
      best = std::max(best, likelihood);
    double chosen = kMaxRatio;
    for (const auto& [ratio, likelihood] : likelihoods_) {
      if (likelihood >= best - kLikelihoodMargin) {
        chosen = ratio;
        break;
      }
    }
    // The spline chosen must explain the means as noise: its standardised innovations' mean square
    // within the chi-square bound (99.9 %), the noise allowed to be as low as the least of kinds' bias
    // makes it at worst, and the innovations white at lags 2-4. Else the component changes in a way no
    // spline holds (a turn rate stepping every other sample, its stamps jittered: mean square 3.5
    // against 2.9, Ljung-Box 150-200 against 30.7; noise alone: under 20), and the twist is followed.
    // The same pass keeps the smoothed sweep, used unless the twist is followed.
    smoothComponent(component, chosen, first, last, true);
    const double dof = static_cast<double>(means_.size() - kDiffuseIntervals);
    if (innovation_square_ > lineTestLimit(dof) / dof / (kLeastOfKindsAtWorst * kLeastOfKindsAtWorst) ||
        ljungBox(standardised_) > kWhitenessLimit)
      chosen = kMaxRatio;
    chosen_ratio_[component] = chosen;
    followed_ = chosen >= kFollowRatio;
  }
}

const MotionSource& TwistMotion::prepare(const MotionSource& raw, TimeNs begin, TimeNs end, TimeNs look_ahead) {
  raw_ = &raw;
  pieces_.clear();
  fastest_change_ = 0.0;
  screws_ = false;
  if (!gatherSamples(raw, begin, end, look_ahead))
    return raw;

  // Interval mean twists.
  const std::size_t intervals = samples_.size() - 1;
  means_.resize(intervals);
  durations_.resize(intervals);
  centres_.resize(intervals);
  for (std::size_t k = 0; k < intervals; ++k) {
    Sample& a = sample(k);
    const Sample& b = sample(k + 1);
    durations_[k] = nsToSeconds(b.time - a.time);
    centres_[k] = nsToSeconds(a.time - sample(0).time) + 0.5 * durations_[k];
    if (a.mean_until != b.time) {  // not computed in an earlier sweep
      const Eigen::Matrix3d relative_rotation = a.rotation.transpose() * b.rotation;
      const Eigen::Vector3d relative_translation = a.rotation.transpose() * (b.translation - a.translation);
      a.mean = se3Log(relative_rotation, relative_translation) / durations_[k];
      a.mean_until = b.time;
    }
    means_[k] = a.mean;
  }
  estimateNoise();

  // The intervals the span touches: from the last sample at or before begin to the first at or after end
  // (the look-ahead's samples only inform the noisy fit).
  // Found by bisection (the samples' times increase): the first is the window's first sample or after
  // it, the last the closing one or before it.
  const auto window = samples_.begin(), closing = samples_.begin() + static_cast<std::ptrdiff_t>(closing_);
  std::size_t first = static_cast<std::size_t>(
      std::upper_bound(window + 1, closing + 1, begin,
                       [](TimeNs t, const Sample* sample) { return t < sample->time; }) -
      window - 1);
  std::size_t last = static_cast<std::size_t>(
      std::lower_bound(window + static_cast<std::ptrdiff_t>(first), closing, end,
                       [](const Sample* sample, TimeNs t) { return sample->time < t; }) -
      window);
  const std::size_t sweep_samples = closing_ + 1;
  if (last == first) {  // a span of one instant on a sample: the interval after it, else before
    if (first + 1 < sweep_samples)
      ++last;
    else
      --first;
  }
  smoothNoisy(first, last);

  Eigen::Matrix3d rotation = sample(first).rotation;
  Eigen::Vector3d translation = sample(first).translation;
  // Where every piece keeps its interval's mean (no noisy component smoothed), a screw piece (no slope,
  // no curvature: Omega(h) is the mean's h) ends where the mean's exponential takes it, at the next
  // sample to rounding: the next piece starts at that sample's own pose.
  const bool through_samples =
      followed_ || std::none_of(noisy_.begin(), noisy_.end(), [](bool noisy) { return noisy; });
  screws_ = true;
  for (std::size_t j = first; j < last; ++j) {
    Piece& piece = pieces_.emplace_back();  // built in place
    piece.time = sample(j).time;
    piece.duration = durations_[j];
    Twist mean, slope, curvature;
    const double h = piece.duration;
    std::array<bool, 6> centred{};
    fitCentredLines(j, slope, centred);
    for (int c = 0; c < 6; ++c) {
      if (centred[static_cast<std::size_t>(c)]) {
        mean[c] = means_[j][c];
        curvature[c] = 0.0;
      } else {
        fitInterval(j, c, mean[c], slope[c], curvature[c]);
      }
      if (std::abs(slope[c]) * h <= floor_[c])
        slope[c] = 0.0;  // a change over the interval below the floor: none
      if (std::abs(curvature[c]) * h * h <= floor_[c])
        curvature[c] = 0.0;
    }
    piece.curved = !curvature.isZero();
    if (!piece.curved) {
      // Omega(h) = mean h + h^3/12 [start, slope] should be the fitted mean's h: solve for the start
      // twist (two fixed-point steps; the bracket is second order).
      Twist centre = mean;
      for (int iteration = 0; iteration < 2; ++iteration)
        centre = mean - (h * h / 12.0) * bracket(centre, slope);
      piece.start_twist = centre - 0.5 * h * slope;
      piece.slope = slope;
    } else {
      // The twist a + b x + q x^2 about the interval's centre (x = t' - h/2), whose mean over it is
      // a + q h^2 / 12: start a - b h/2 + q h^2/4, slope b - q h, curvature q; the start solved such
      // that Omega(h) is the mean's h, the same way.
      piece.curvature = curvature;
      piece.slope = slope - h * curvature;
      const Twist offset = -0.5 * h * slope + (h * h / 4.0) * curvature;
      Twist centre = mean - (h * h / 12.0) * curvature;
      for (int iteration = 0; iteration < 2; ++iteration) {
        piece.start_twist = centre + offset;
        const Twist excess = piece.omega(h) / h - mean;
        centre -= excess;
      }
      piece.start_twist = centre + offset;
    }
    screws_ = screws_ && !piece.curved && slope.isZero();
    const Twist end_slope = piece.slope + 2.0 * h * piece.curvature;
    fastest_change_ = std::max({fastest_change_, slope.head<3>().norm() + kKnotReach * slope.tail<3>().norm(),
                                end_slope.head<3>().norm() + kKnotReach * end_slope.tail<3>().norm(),
                                piece.slope.head<3>().norm() + kKnotReach * piece.slope.tail<3>().norm()});
    piece.rotation = rotation;
    piece.translation = translation;
    // The next piece starts where this one ends.
    if (through_samples && !piece.curved && slope.isZero()) {
      rotation = sample(j + 1).rotation;
      translation = sample(j + 1).translation;
      continue;
    }
    Eigen::Matrix3d step_rotation;
    Eigen::Vector3d step_translation;
    se3Exp(piece.omega(h), step_rotation, step_translation);
    translation += rotation * step_translation;
    rotation = rotation * step_rotation;
  }
  end_rotation_ = rotation;
  end_translation_ = translation;
  end_time_ = sample(last).time;
  return *this;
}

mrpt::poses::CPose3D TwistMotion::basePose(TimeNs time) const {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  baseTransform(time, rotation, translation);
  return detail::poseOf(rotation, translation);
}

void TwistMotion::baseTransform(TimeNs time, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const {
  if (pieces_.empty() || time < pieces_.front().time || time > end_time_) {
    throw MotionUnavailable(time, "time " + std::to_string(time) + " ns is outside the fitted motion");
  }
  if (time == end_time_) {
    rotation = end_rotation_;
    translation = end_translation_;
    return;
  }
  // The last piece starting at or before `time`: the knots ask in time order, so most often the one
  // asked last or the next.
  const std::size_t count = pieces_.size();
  const auto holds = [&](std::size_t k) {
    return pieces_[k].time <= time && (k + 1 == count || time < pieces_[k + 1].time);
  };
  std::size_t index = std::min(piece_hint_, count - 1);
  if (!holds(index)) {
    if (index + 1 < count && holds(index + 1)) {
      ++index;
    } else {
      index = static_cast<std::size_t>(std::upper_bound(pieces_.begin(), pieces_.end(), time,
                                                        [](TimeNs t, const Piece& piece) { return t < piece.time; }) -
                                       pieces_.begin()) -
              1;
    }
  }
  piece_hint_ = index;
  const Piece& piece = pieces_[index];
  const double tau = nsToSeconds(time - piece.time);
  Eigen::Matrix3d step_rotation;
  Eigen::Vector3d step_translation;
  if (tau == 0.0 && piece.start_twist.allFinite() && piece.slope.allFinite() &&
      (!piece.curved || piece.curvature.allFinite()) && !hasNegativeZero(piece.translation)) {
    // At the piece's start (a knot on a sample): Omega(0) is zeros (of either sign), whose exponential
    // is the identity exactly, its translation zeros, which leave a translation without a -0 as it is.
    step_rotation.setIdentity();
    rotation = piece.rotation * step_rotation;
    translation = piece.translation;
    return;
  }
  se3Exp(piece.omega(tau), step_rotation, step_translation);
  rotation = piece.rotation * step_rotation;
  translation = piece.translation + piece.rotation * step_translation;
}

double TwistMotion::knotInterval(double requested) const {
  if (!(fastest_change_ > 0.0))
    return requested;
  return std::min(requested, std::max(kMinKnotSpacing, std::sqrt(8.0 * kKnotTolerance / fastest_change_)));
}

void TwistMotion::appendSampleTimes(TimeNs begin, TimeNs end, std::vector<TimeNs>& times) const {
  for (const Piece& piece : pieces_) {
    if (piece.time > begin && piece.time < end)
      times.push_back(piece.time);
  }
}

TimeNs TwistMotion::longestGap(TimeNs begin, TimeNs end) const {
  return raw_ ? raw_->longestGap(begin, end) : 0;
}

}  // namespace lidar_deskew::core
