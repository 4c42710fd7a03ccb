#include "lidar_deskew/core/rebin.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "fast_atan2.h"
#include "kth_smallest.h"
#include "simd.h"

namespace lidar_deskew::core {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
/// Tolerance on the segment parameter of a crossing: a ray through a contour's vertex meets it.
constexpr double kVertexTolerance = 1e-9;

inline double cross(double ax, double ay, double bx, double by) {
  return ax * by - ay * bx;
}

/// [rad] bearings are off by at most this: intervals of bins are widened by it (the crossing test is exact).
constexpr double kBearingError = 2.0 * detail::kFastAtan2Error;
using detail::fastAtan2;

/// `delta` [rad], a difference of two bearings in [-pi, pi], moved into [-pi, pi].
inline double wrapDelta(double delta) {
  if (delta > M_PI)
    return delta - kTwoPi;
  if (delta < -M_PI)
    return delta + kTwoPi;
  return delta;
}

/// [m] the flat-point tolerance never goes below this (float32 ranges, the correction's own error).
constexpr double kFlatToleranceFloor = 1e-3;
/// The flat-point tolerance in medians of the distance of a point from its neighbours' line: range noise
/// sigma gives a median of about 0.8 sigma, so 4 medians keep 99 % of the points of a noisy wall flat.
constexpr double kFlatToleranceMedians = 4.0;
/// A step's far contour is continued behind the near one only where it runs at most this far along per
/// metre sideways (walls seen up to about 72 deg off-normal): beyond, its end is too uncertain.
constexpr double kMaxStepSlant = 3.0;
/// [m] a step's far contour is continued (and two flat points farther apart than the gap joined) only where
/// the error its end segment's noise gives over the continuation (the flat-point tolerance, times one plus
/// the continuation's length in segment lengths) stays below this; otherwise the step is joined as before (a
/// chord, or two contour ends).
constexpr double kStepErrorBudget = 0.005;
/// [m] Where the scan's noise is within kStepErrorBudget, what the returns cannot tell is left empty
/// rather than guessed beyond this error: a contour's end (or a lone return's facet) is followed at most
/// this far past its last return (the surface may end right there), and a chord (two returns on no
/// surface, corner or step the rules know) fills its bins only when it is at most twice this long (the
/// true surface between may be a corner as deep as half the chord).
constexpr double kGuessBudget = 0.01;
/// Neighbours farther apart than the gap (one of them flat) are one surface up to this many gaps apart.
constexpr double kFlatJoinGaps = 3.0;
/// A step, or a surface whose points are farther apart than the gap, bridges at most this many bins
/// (more: the points are not neighbours on the grid, e.g. the first and the last beam of a full circle
/// while spinning).
constexpr double kMaxStepBins = 2.0;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
/// At most this many points' distances estimate the median (every k-th point).
constexpr std::size_t kNoiseSampleSize = 128;
/// The noise sample's median is selected within one of these buckets of its values (noiseBucket()).
constexpr std::size_t kNoiseBuckets = 256;
/// Which bucket a distance [m] (non-negative) falls in: by its bits (non-negative doubles order as
/// their bits do), four buckets per binade from 2^-50 m to 2^14 m, those beyond in the first or the last
/// (+inf and NaN in the last).
inline std::size_t noiseBucket(double distance) {
  std::uint64_t bits;
  std::memcpy(&bits, &distance, sizeof bits);
  constexpr std::uint64_t kFirst = (1023u - 50u) << 2;  // the exponent and two bits of the mantissa of 2^-50
  const std::uint64_t key = bits >> 50;
  return static_cast<std::size_t>(key < kFirst ? 0
                                               : std::min<std::uint64_t>(key - kFirst, kNoiseBuckets - 1));
}

/// `angle` [rad] (finite, within a few turns) moved into [0, 2pi) without a library call.
inline double wrapToTurn(double angle) {
  if (std::abs(angle) > 4.0 * kTwoPi)  // far out (never from a validated scan): one library call
    angle = std::fmod(angle, kTwoPi);
  while (angle < 0.0)
    angle += kTwoPi;
  while (angle >= kTwoPi)
    angle -= kTwoPi;
  return angle;
}

/// Throws InvalidInput when rebin() cannot use `grid`: a zero or non-finite increment with more than one
/// bin, a non-finite angle_min, or an increment beyond +-2pi.
void checkGrid(const AngleGrid& grid) {
  const std::size_t bin_count = grid.count;
  const double increment = grid.angle_increment;
  if (bin_count > 1 && (!std::isfinite(increment) || increment == 0.0)) {
    throw InvalidInput("angle_increment",
                       "must be finite and non-zero to re-bin " + std::to_string(bin_count) + " bins");
  }
  if (!std::isfinite(grid.angle_min))
    throw InvalidInput("angle_min", "must be finite");
  if (std::abs(increment) > kTwoPi)
    throw InvalidInput("angle_increment", "must be within +-2 pi rad");
}

}  // namespace

/// The bins of one (checked) grid whose ray angles lie in a given interval.
class ScanRebinner::BinSweep {
 public:
  explicit BinSweep(const AngleGrid& grid)
      : bin_count_(grid.count),
        angle_min_(grid.angle_min),
        increment_(grid.angle_increment),
        abs_increment_(std::abs(increment_)),
        inverse_increment_(abs_increment_ > 0.0 ? 1.0 / abs_increment_ : 0.0),
        wider_than_a_turn_(abs_increment_ * static_cast<double>(bin_count_ - 1) >= kTwoPi - 1e-9),
        full_circle_(abs_increment_ * static_cast<double>(bin_count_) >= kTwoPi - 0.5 * abs_increment_) {}

  std::size_t binCount() const { return bin_count_; }
  /// [rad] |angle_increment|
  double absIncrement() const { return abs_increment_; }
  /// Whether the grid closes the circle, so its last bin neighbours its first.
  bool isFullCircle() const { return full_circle_; }

  /// visit(bin) for the bins whose ray angle lies in [low, low + width] [rad] (mod 2pi), width <= pi.
  template <typename Visit>
  void forEachBinIn(double low, double width, Visit&& visit) const {
    if (bin_count_ == 0)
      return;
    if (bin_count_ == 1) {
      const double offset = wrapToTurn(angle_min_ - low);
      if (offset <= width + 1e-12 || offset >= kTwoPi - 1e-12)
        visit(std::size_t{0});
      return;
    }
    const double start = wrapToTurn(increment_ > 0.0 ? low - angle_min_ : angle_min_ - (low + width));
    visitBinsFrom(start, width, visit);
    if (start + width >= kTwoPi - 1e-9)
      visitBinsFrom(start - kTwoPi, width, visit);  // past the grid's wrap
    if (wider_than_a_turn_)
      visitBinsFrom(start + kTwoPi, width, visit);  // e.g. 361 x 1 deg
  }

 private:
  /// visit(bin) for the bins from `start` to `start + width`, angles [rad] from angle_min along the grid's
  /// direction, clipped to the grid.
  template <typename Visit>
  void visitBinsFrom(double start, double width, Visit& visit) const {
    const double first = std::max(std::ceil(start * inverse_increment_ - 1e-6), 0.0);
    const double last = std::min(std::floor((start + width) * inverse_increment_ + 1e-6),
                                 static_cast<double>(bin_count_ - 1));
    for (double b = first; b <= last; b += 1.0)
      visit(static_cast<std::size_t>(b));
  }

  std::size_t bin_count_;
  double angle_min_;  // [rad]
  double increment_;  // [rad]
  double abs_increment_;
  double inverse_increment_;  // [1/rad] 0 for a zero increment
  bool wider_than_a_turn_;    // the first and the last bin can lie on the same ray
  bool full_circle_;
};

void RebinConfig::validate() const {
  if (!std::isfinite(min_gap) || min_gap < 0.0) {
    throw InvalidInput("rebin_min_gap", "must be >= 0 m, got " + std::to_string(min_gap));
  }
  if (!std::isfinite(gap_factor) || gap_factor < 0.0) {
    throw InvalidInput("rebin_gap_factor", "must be >= 0, got " + std::to_string(gap_factor));
  }
}

float noReturnValue(const PlanarScan& scan) {
  const std::size_t first = ReturnTest(scan).firstWithout(scan.ranges.data(), scan.ranges.size());
  return first < scan.ranges.size() ? scan.ranges[first] : std::numeric_limits<float>::infinity();
}

ScanRebinner::ScanRebinner(const RebinConfig& config) : config_(config) {
  config_.validate();
}

namespace {

/// A point's running bin position moves at most this many rays from its hint before it is found again
/// from the point's bearing (a contour start after a long gap, a fold-over).
constexpr int kMaxWalk = 16;
/// Running bin positions need the rays of the whole circle; grids finer than this many rays per turn
/// (or wider than a turn) are swept by bearing instead.
constexpr double kMaxRunningRays = 1 << 16;
/// locate() reads up to this many rays past its hint (the last ray at most).
constexpr std::size_t kRayPadding = 4;
/// A point lies on a ray (a segment ending there meets it) when within this times |x| + |y| of it: rounding.
constexpr double kOnRayTolerance = 1e-9;
/// The running bin position of a point not found: far below any ray, so that no ray computed from it
/// (one on or after) is one.
constexpr std::int32_t kNoPosition = -(1 << 28);
/// locatePoints(): a point's position in float is not used where its bearing lies within this [rad] of a
/// ray (the sum of its rounding errors and of bearingInFloat's, about 4.5e-6, with margin), nor where
/// max(|x|, |y|) [m] lies outside these bounds (float's range); -1 marks it.
constexpr double kBearingErrorFloat = 1e-5;
constexpr float kMinFloatScale = 1e-18f, kMaxFloatScale = 1e18f;
constexpr std::int32_t kNearRay = -1;
/// [rad] float positions only for grids whose angle_min is within this (rays' angles exact to 1e-13 rad).
constexpr double kMaxFloatAngleMin = 1e3;

/// A float's bits, and the float of bits: selects by masks for loops the compiler vectorises (it moves
/// arithmetic selected by a condition into a branch, which it does not vectorise).
inline std::uint32_t bitsOf(float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, sizeof bits);
  return bits;
}
inline float floatOf(std::uint32_t bits) {
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}
/// The same for doubles (C++20's std::bit_cast).
template <typename To, typename From>
inline To bitCast(From value) {
  static_assert(sizeof(To) == sizeof(From), "same size");
  To result;
  std::memcpy(&result, &value, sizeof result);
  return result;
}
/// All ones when `condition`, else 0.
inline std::uint32_t maskOf(bool condition) {
  return 0u - static_cast<std::uint32_t>(condition);
}
constexpr std::uint64_t kMaxInt64 = 0x7fffffffffffffffu;
constexpr std::uint32_t kSignBit = 0x80000000u;

/// The bearing [rad] of (px, py) in float, from a = min(|px|, |py|) / max(|px|, |py|): an odd polynomial for
/// atan on [0, 1] (least squares, error 1.7e-6 rad) and the octant's symmetries by masks.
inline float bearingInFloat(float a, float px, float py) {
  const float s = a * a;
  const float r =
      a * (0.99997722f +
           s * (-0.33262283f + s * (0.19354038f + s * (-0.11642648f + s * (0.05264735f + s * -0.01171913f)))));
  const std::uint32_t steep = maskOf(std::abs(py) > std::abs(px));  // pi/2 - r
  const std::uint32_t left = maskOf(px < 0.0f);                      // pi - that
  const float octant = floatOf(bitsOf(static_cast<float>(M_PI_2)) & steep) + floatOf(bitsOf(r) ^ (steep & kSignBit));
  const float half = floatOf(bitsOf(static_cast<float>(M_PI)) & left) + floatOf(bitsOf(octant) ^ (left & kSignBit));
  return floatOf(bitsOf(half) ^ (maskOf(py < 0.0f) & kSignBit));  // below the x axis: negated
}

/// Links k < count from (px, py)[k] to (px, py)[k + 1], each crossing the ray (cosine, sine)[k]: keeps the
/// crossing's range in best[k] when positive and nearer (restrict: no overlap tests, which cost short runs).
inline void crossConsecutiveRays(std::size_t count, const double* __restrict px, const double* __restrict py,
                                 const double* __restrict cosine, const double* __restrict sine,
                                 double* __restrict best) {
  for (std::size_t k = 0; k < count; ++k) {
    const double ex = px[k + 1] - px[k], ey = py[k + 1] - py[k];
    const double numerator = px[k] * ey - py[k] * ex;
    const double range = numerator / (cosine[k] * ey - sine[k] * ex);
    best[k] = (range > 0.0) & (range < best[k]) ? range : best[k];
  }
}

/// The intensity where a ray from the origin through (ray_x, ray_y) meets the segment from a to b at
/// `range`, with numerator = a x (b - a) (as the crossings compute it): interpolated between the ends'.
inline float intensityAt(double ax, double ay, double ray_x, double ray_y, double range, double numerator,
                         float a_intensity, float b_intensity) {
  const double u = std::min(std::max((ax * ray_y - ay * ray_x) * range / numerator, 0.0), 1.0);
  return static_cast<float>((1.0 - u) * a_intensity + u * b_intensity);
}

/// crossConsecutiveRays() with intensities: where a ray keeps the crossing, it takes the intensity
/// interpolated there between the link's points (as crossSurface() does, in its order of operations).
inline void crossConsecutiveRays(std::size_t count, const double* __restrict px, const double* __restrict py,
                                 const float* __restrict intensity, const double* __restrict cosine,
                                 const double* __restrict sine, double* __restrict best,
                                 float* __restrict best_intensity) {
  for (std::size_t k = 0; k < count; ++k) {
    const double ex = px[k + 1] - px[k], ey = py[k + 1] - py[k];
    const double numerator = px[k] * ey - py[k] * ex;
    const double ray_x = cosine[k], ray_y = sine[k];
    const double range = numerator / (ray_x * ey - ray_y * ex);
    const float value =
        intensityAt(px[k], py[k], ray_x, ray_y, range, numerator, intensity[k], intensity[k + 1]);
    const bool keep = (range > 0.0) & (range < best[k]);
    best[k] = keep ? range : best[k];
    best_intensity[k] = keep ? value : best_intensity[k];
  }
}

}  // namespace

/// The rays as running bin positions see them: side(ray, p) is how far p lies past the ray in the grid's
/// direction (negative: before it).
struct ScanRebinner::Rays {
  const double* side_cos;  // the grid's direction times each ray's direction (kRayPadding copies of the
  const double* side_sin;  // first rays after the last)
  std::int32_t count;
  double direction;  // the sign of the increment
  double angle_min, abs_increment;

  double side(std::int32_t ray, double px, double py) const {
    return side_cos[ray] * py - side_sin[ray] * px;
  }
  std::int32_t next(std::int32_t ray) const { return ray + 1 == count ? 0 : ray + 1; }
  std::int32_t previous(std::int32_t ray) const { return ray == 0 ? count - 1 : ray - 1; }

  /// The ray (px, py) lies on or past, whose next ray it lies before, walking from `ray`, with side() of
  /// both (`low` >= 0, `high` < 0); -1 when not within kMaxWalk rays.
  std::int32_t walk(std::int32_t ray, double px, double py, double& low, double& high) const {
    double at = side(ray, px, py);
    for (int step = 0; step < kMaxWalk; ++step) {
      if (at < 0.0) {
        ray = previous(ray);
        at = side(ray, px, py);
        continue;
      }
      const std::int32_t after = next(ray);
      const double at_after = side(after, px, py);
      if (at_after < 0.0) {
        low = at;
        high = at_after;
        return ray;
      }
      ray = after;
      at = at_after;
    }
    return -1;
  }

  /// As walk(), trying the hint's position and the next first (a scan that turned with the sensor spreads
  /// its points over more rays than its beams), and from the point's bearing when far from the hint.
  std::int32_t locate(double px, double py, std::int32_t hint, double& low, double& high) const {
    const double at_next = side(hint + 1, px, py);
    if (at_next >= 0.0) {
      const double at_after = side(hint + 2, px, py);
      if (at_after < 0.0) {
        low = at_next;
        high = at_after;
        return next(hint);
      }
      const double at_further = side(hint + 3, px, py);
      if (at_further < 0.0) {
        low = at_after;
        high = at_further;
        return next(next(hint));
      }
    } else {
      const double at = side(hint, px, py);
      if (at >= 0.0) {
        low = at;
        high = at_next;
        return hint;
      }
    }
    return locateFar(px, py, hint, low, high);
  }

  [[gnu::noinline]] std::int32_t locateFar(double px, double py, std::int32_t hint, double& low,
                                           double& high) const {
    std::int32_t found = walk(hint, px, py, low, high);
    if (found >= 0)
      return found;
    const double offset = wrapToTurn(direction * (fastAtan2(py, px) - angle_min));
    const double ray = std::floor(offset / abs_increment);
    found = walk(static_cast<std::int32_t>(std::min(std::max(ray, 0.0), count - 1.0)), px, py, low, high);
    if (found >= 0)
      return found;
    for (std::int32_t candidate = 0; candidate < count; ++candidate) {  // rounding at a ray: never so far
      const double at = side(candidate, px, py), after = side(next(candidate), px, py);
      if (at >= 0.0 && after < 0.0) {
        low = at;
        high = after;
        return candidate;
      }
    }
    return -1;
  }
};

ScanRebinner::Rays ScanRebinner::rays(double abs_increment) const {
  return {side_cos_.data(),
          side_sin_.data(),
          static_cast<std::int32_t>(ray_count_),
          direction_,
          static_cast<double>(rays_grid_.angle_min),
          abs_increment};
}

void ScanRebinner::crossRays(const RayPoint& a, const RayPoint& b) {
  // The rays between the two positions cross the segment; the ray at or before the earlier point and the
  // one after the later point only when that point lies (almost) on it: within the vertex tolerance of |e|
  // (|side()| is the point's distance from the ray).
  const std::int32_t ray_count = static_cast<std::int32_t>(ray_count_);
  const double near_ray = 2.0 * kVertexTolerance * (std::abs(b.x - a.x) + std::abs(b.y - a.y));
  std::int32_t forward = b.ray - a.ray;
  forward += forward < 0 ? ray_count : 0;
  std::int32_t first = a.ray;
  bool test_first = a.low <= near_ray, test_last = -b.high <= near_ray;
  if (forward == 0) {
    test_first = test_first || b.low <= near_ray;
    test_last = test_last || -a.high <= near_ray;
  } else if (forward > ray_count / 2) {  // b before a in the grid's direction
    forward = ray_count - forward;
    first = b.ray;
    test_first = b.low <= near_ray;
    test_last = -a.high <= near_ray;
  }
  std::int32_t ray = first + (test_first ? 0 : 1);
  ray -= ray == ray_count ? ray_count : 0;
  offerRays(ray, forward + (test_first ? 1 : 0) + (test_last ? 1 : 0), a.x, a.y, a.intensity, b.x, b.y,
            b.intensity);
}

void ScanRebinner::offerRays(std::int32_t ray, std::int32_t count, double ax, double ay, float a_intensity,
                             double bx, double by, float b_intensity) {
  // Between the points' positions, each ray meets the segment (u within [0, 1] but for rounding): no test
  // of its own. A ray parallel to it gives inf or NaN, which no ray keeps.
  const std::int32_t ray_count = static_cast<std::int32_t>(ray_count_);
  const double ex = bx - ax, ey = by - ay;
  const double numerator = ax * ey - ay * ex;
  const double* const ray_cos = ray_cos_.data();
  const double* const ray_sin = ray_sin_.data();
  double* const best_range = best_range_.data();
  for (; count > 0; --count, ray = ray + 1 == ray_count ? 0 : ray + 1) {
    const double ray_x = ray_cos[ray], ray_y = ray_sin[ray];
    const double range = numerator / (ray_x * ey - ray_y * ex);
    if (!(range > 0.0 && range < best_range[ray]))
      continue;
    best_range[ray] = range;
    if (with_intensities_) {
      best_intensity_[ray] = intensityAt(ax, ay, ray_x, ray_y, range, numerator, a_intensity, b_intensity);
    }
  }
}

unsigned ScanRebinner::onRay(std::size_t j) const {
  const Rays rays = this->rays(0.0);
  const std::int32_t ray = position_[j];
  const double on = kOnRayTolerance * (std::abs(x_[j]) + std::abs(y_[j]));
  return (rays.side(ray, x_[j], y_[j]) <= on ? 1u : 0u) | (-rays.side(ray + 1, x_[j], y_[j]) <= on ? 2u : 0u);
}

void ScanRebinner::offerOwnRay(std::size_t j, const Points& points) {
  if (!running_ || position_[j] < 0 || !near_ray_[j])
    return;
  const unsigned on = onRay(j);
  const std::size_t ray = static_cast<std::size_t>(position_[j]);
  if (on & 1u)
    offer(ray, rangeOf(j), points[j].intensity);
  if (on & 2u)
    offer(ray + 1 == ray_count_ ? 0 : ray + 1, rangeOf(j), points[j].intensity);
}

bool ScanRebinner::crossSurface(std::size_t a, std::size_t b, const Points& points) {
  // As crossRays(), with whether each point lies on its position's ray or the next (onRay()); only for
  // segments less than a quarter turn wide, found in either direction.
  const std::int32_t ray_count = static_cast<std::int32_t>(ray_count_);
  const std::int32_t* const position = position_.data();
  if ((position[a] | position[b]) < 0)
    return false;
  std::int32_t forward = position[b] - position[a];
  forward += forward < 0 ? ray_count : 0;
  const std::int32_t quarter = ray_count / 4;
  if (forward > quarter) {
    if (forward < ray_count - quarter)
      return false;   // a quarter turn wide or more: by bearing
    std::swap(a, b);  // b before a in the grid's direction
    forward = ray_count - forward;
  }
  const unsigned on_a = near_ray_[a] ? onRay(a) : 0u, on_b = near_ray_[b] ? onRay(b) : 0u;
  // bit 0: on its position's ray, bit 1: on the next ray; both points between the same two rays: either
  // one on them counts.
  const unsigned first_bit = (on_a | (forward == 0 ? on_b : 0u)) & 1u;
  const unsigned last_bit = ((on_b | (forward == 0 ? on_a : 0u)) >> 1) & 1u;
  std::int32_t ray = position[a] + 1 - static_cast<std::int32_t>(first_bit);
  ray -= ray == ray_count ? ray_count : 0;
  offerRays(ray, forward + static_cast<std::int32_t>(first_bit + last_bit), x_[a], y_[a], points[a].intensity,
            x_[b], y_[b], points[b].intensity);
  return true;
}

void ScanRebinner::updateRays(const AngleGrid& grid) {
  if (ray_cos_.size() == ray_count_ + kRayPadding && rays_grid_.count == grid.count &&
      rays_grid_.angle_min == grid.angle_min && rays_grid_.angle_increment == grid.angle_increment) {
    return;
  }
  rays_grid_ = grid;
  const double abs_increment = std::abs(static_cast<double>(grid.angle_increment));
  // Rays past the grid's last bin up to a full turn (offered, never written out) let a bin position run
  // modulo ray_count_ around the circle.
  const double rays_per_turn = abs_increment > 0.0 ? (kTwoPi - 1e-9) / abs_increment : kInfinity;
  running_ = grid.count > 1 && rays_per_turn <= kMaxRunningRays &&
             abs_increment * static_cast<double>(grid.count - 1) < kTwoPi - 1e-9;
  ray_count_ =
      running_ ? std::max(grid.count, static_cast<std::size_t>(std::floor(rays_per_turn)) + 1) : grid.count;
  direction_ = grid.angle_increment < 0.0f ? -1.0 : 1.0;
  ray_cos_.resize(ray_count_ + kRayPadding);
  ray_sin_.resize(ray_count_ + kRayPadding);
  side_cos_.resize(ray_count_ + kRayPadding);
  side_sin_.resize(ray_count_ + kRayPadding);
  for (std::size_t b = 0; b < ray_count_ + kRayPadding && ray_count_ > 0; ++b) {
    const double angle =
        static_cast<double>(grid.angle_min) + static_cast<double>(b % ray_count_) * grid.angle_increment;
    ray_cos_[b] = std::cos(angle);
    ray_sin_[b] = std::sin(angle);
    side_cos_[b] = direction_ * ray_cos_[b];
    side_sin_[b] = direction_ * ray_sin_[b];
  }
  // Positions in float (locatePoints()) where the rays are within a quarter turn of each other and their
  // angles in double are exact to far within its error bound; rays relative to the grid's first, wrapped
  // into [0, 2pi) in double.
  float_positions_ = running_ && abs_increment < 0.5 * M_PI_2 && std::abs(grid.angle_min) < kMaxFloatAngleMin;
  bearing_origin_ = static_cast<float>(wrapToTurn(grid.angle_min));
  bins_per_radian_ = running_ ? static_cast<float>(1.0 / abs_increment) : 0.0f;
  position_guard_ = static_cast<float>(kBearingErrorFloat / abs_increment + std::ldexp(ray_count_, -21));
  last_sure_bin_ = static_cast<float>(kTwoPi / abs_increment) - position_guard_;
  // Every bin starts with no crossing; writeNearestCrossings() leaves them so for the next scan.
  best_range_.assign(ray_count_, kInfinity);
  best_intensity_.assign(ray_count_, 0.0f);
  converted_.resize(ray_count_);
}

void ScanRebinner::rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return,
                         RebinnedScan& out) {
  checkGrid(grid);
  updateRays(grid);
  if (bins_in_use_) {  // the last scan stopped (an allocation failed) before leaving its bins empty
    std::fill(best_range_.begin(), best_range_.end(), kInfinity);
    std::fill(best_intensity_.begin(), best_intensity_.end(), 0.0f);
  }
  with_intensities_ = corrected.has_intensities;
  const BinSweep sweep(grid);
  readPoints(corrected.points, sweep);
  classifyLinks();
  classifyRareLinks(sweep);
  bins_in_use_ = true;
  traceContours(corrected.points, sweep);
  writeNearestCrossings(no_return, out);
  bins_in_use_ = false;
}

LIDAR_DESKEW_AVX2_CLONES void ScanRebinner::locatePoints(const Rays& rays) {
  const std::size_t n = x_.size();
  const double* const x = x_.data();
  const double* const y = y_.data();
  std::int32_t* const position = position_.data();
  unsigned char* const near_ray = near_ray_.data();
  // Every point's ray from its bearing in float, in a loop of arithmetic alone on 32-bit lanes (vectorised):
  // kNearRay where the bearing lies within its error bound (kBearingErrorFloat) of a ray, or the point is
  // not of a size float holds. Elsewhere the point lies strictly between that ray and the next, as side()
  // finds.
  if (float_positions_) {
    const float* const x_float = x_float_.data();
    const float* const y_float = y_float_.data();
    const float origin = bearing_origin_, direction = static_cast<float>(direction_);
    const float bins_per_radian = bins_per_radian_, guard = position_guard_, last_sure = last_sure_bin_;
    constexpr float kTurn = static_cast<float>(kTwoPi);
    for (std::size_t j = 0; j < n; ++j) {
      const float px = x_float[j], py = y_float[j];
      const float ax = std::abs(px), ay = std::abs(py);
      const float high = std::max(ax, ay), low = std::min(ax, ay);
      const bool sane = (high > kMinFloatScale) & (high < kMaxFloatScale);
      const float bearing = bearingInFloat(low / std::max(high, kMinFloatScale), px, py);
      const float offset = direction * (bearing - origin);  // within (-3pi, 3pi): into [0, 2pi)
      const float turn = floatOf(bitsOf(kTurn) & maskOf(offset < 0.0f)) - floatOf(bitsOf(kTurn) & maskOf(offset >= kTurn));
      const float wrapped = offset + turn + floatOf(bitsOf(kTurn) & maskOf(offset < -kTurn));
      const float bins = floatOf(bitsOf(wrapped * bins_per_radian) & maskOf(sane));  // (not NaN: 0)
      const std::int32_t ray = static_cast<std::int32_t>(bins);
      const float fraction = bins - static_cast<float>(ray);
      const std::uint32_t sure =
          maskOf(sane & (fraction > guard) & (fraction < 1.0f - guard) & (bins < last_sure));
      position[j] = static_cast<std::int32_t>((static_cast<std::uint32_t>(ray) & sure) |
                                              (static_cast<std::uint32_t>(kNearRay) & ~sure));
    }
    for (std::size_t j = 0; j < n; ++j)
      near_ray[j] = position[j] == kNearRay;
  } else {
    std::fill(position, position + n, kNearRay);
    std::fill(near_ray, near_ray + n, 1);
  }
  // The others as before: walking from the last point's ray found (side() decides, in double).
  for (const unsigned char* found = static_cast<const unsigned char*>(std::memchr(near_ray, 1, n)); found;) {
    const std::size_t j = static_cast<std::size_t>(found - near_ray);
    std::size_t before = j;
    while (before > 0 && position[before - 1] < 0)
      --before;
    double low = 0.0, high = 0.0;
    const std::int32_t ray = rays.locate(x[j], y[j], before > 0 ? position[before - 1] : 0, low, high);
    position[j] = ray >= 0 ? ray : kNoPosition;
    found = j + 1 < n ? static_cast<const unsigned char*>(std::memchr(near_ray + j + 1, 1, n - j - 1)) : nullptr;
  }
}

LIDAR_DESKEW_AVX2_CLONES void ScanRebinner::readPoints(const Points& points, const BinSweep& sweep) {
  const std::size_t n = points.size();
  x_.resize(n);
  y_.resize(n);
  x_float_.resize(n);
  y_float_.resize(n);
  scale_.resize(n);
  range_.resize(n);
  beam_.resize(n);
  cross_.resize(n);
  length2_.resize(n);
  position_.resize(n);
  near_ray_.resize(n);
  has_next_.resize(n);
  joined_.resize(n);
  run_kind_.resize(n + 8);  // (nextSpecial() reads whole words)
  join_test_.resize(n);
  line_.resize(n);
  // whole words of 8 bytes for classifyLinks(): the bytes past the last point stay 0
  const std::size_t padded = (n + 7) / 8 * 8;
  candidate_.resize(padded);
  std::fill(candidate_.begin() + static_cast<std::ptrdiff_t>(n), candidate_.end(), 0);
  candidate_count_ = 0;
  wraps_ = false;
  if (n == 0)
    return;
  // Plain pointers and locals: stores through the byte arrays could alias any member.
  double* const x = x_.data();
  double* const y = y_.data();
  float* const x_float = x_float_.data();
  float* const y_float = y_float_.data();
  double* const scale = scale_.data();
  double* const range = range_.data();
  std::uint32_t* const beam = beam_.data();
  unsigned char* const has_next = has_next_.data();
  unsigned char* const joined = joined_.data();
  double* const cross_product = cross_.data();
  double* const length2 = length2_.data();
  unsigned char* const candidate = candidate_.data();
  const bool running = running_;
  const Rays rays = this->rays(sweep.absIncrement());
  // The points into plain arrays (in float too, for locatePoints()), which are neighbours (beam index + 1).
  // Finite when every |x| + |y| is (checked after).
  bool finite = true;
  std::size_t i = 0;
#if defined(__SSE2__)
  // Four points at a time, their x/y pairs loaded as such (SSE2 is part of x86-64): the same operations as
  // below, in two lanes.
  const __m128d sign = _mm_set1_pd(-0.0), largest = _mm_set1_pd(std::numeric_limits<double>::max());
  __m128d sizes_finite = _mm_cmpeq_pd(largest, largest);  // all ones
  for (; i + 4 <= n; i += 4) {
    __m128 float_x = _mm_setzero_ps(), float_y = _mm_setzero_ps();
    for (std::size_t half = 0; half < 4; half += 2) {
      const __m128d first = _mm_loadu_pd(points[i + half].position.data());  // x, y
      const __m128d second = _mm_loadu_pd(points[i + half + 1].position.data());
      const __m128d px = _mm_unpacklo_pd(first, second), py = _mm_unpackhi_pd(first, second);
      const __m128d abs_x = _mm_andnot_pd(sign, px), abs_y = _mm_andnot_pd(sign, py);
      sizes_finite = _mm_and_pd(sizes_finite, _mm_cmple_pd(_mm_add_pd(abs_x, abs_y), largest));
      _mm_storeu_pd(x + i + half, px);
      _mm_storeu_pd(y + i + half, py);
      _mm_storeu_pd(scale + i + half, _mm_max_pd(abs_x, abs_y));  // (equal: the same value)
      _mm_storeu_pd(range + i + half, _mm_sqrt_pd(_mm_add_pd(_mm_mul_pd(px, px), _mm_mul_pd(py, py))));
      float_x = half == 0 ? _mm_cvtpd_ps(px) : _mm_movelh_ps(float_x, _mm_cvtpd_ps(px));
      float_y = half == 0 ? _mm_cvtpd_ps(py) : _mm_movelh_ps(float_y, _mm_cvtpd_ps(py));
    }
    _mm_storeu_ps(x_float + i, float_x);
    _mm_storeu_ps(y_float + i, float_y);
    for (std::size_t k = i; k < i + 4; ++k)
      beam[k] = points[k].beam_index;
  }
  finite = _mm_movemask_pd(sizes_finite) == 3;
#endif
  for (; i < n; ++i) {
    const double px = points[i].position.x(), py = points[i].position.y();
    const double size = std::abs(px) + std::abs(py);
    finite &= size <= std::numeric_limits<double>::max();
    x[i] = px;
    y[i] = py;
    x_float[i] = static_cast<float>(px);
    y_float[i] = static_cast<float>(py);
    scale[i] = std::max(std::abs(px), std::abs(py));
    range[i] = std::sqrt(px * px + py * py);
    beam[i] = points[i].beam_index;
  }
  if (with_intensities_) {
    intensity_.resize(n);
    for (std::size_t j = 0; j < n; ++j)
      intensity_[j] = points[j].intensity;
  }
  if (!finite) {
    for (std::size_t j = 0; j < n; ++j) {
      if (!std::isfinite(x[j]) || !std::isfinite(y[j]))
        throw InvalidInput("points", "corrected point " + std::to_string(j) + " is not finite");
    }
  }
  for (std::size_t j = 0; j + 1 < n; ++j)
    has_next[j] = beam[j + 1] == beam[j] + 1;
  if (running)
    locatePoints(rays);
  // For a full-circle grid the last beam also neighbours the first.
  wraps_ = sweep.isFullCircle() && n > 2 && points.front().beam_index == 0 &&
           points.back().beam_index + 1 == sweep.binCount();
  has_next[n - 1] = wraps_;
  // Joins: within min_gap + gap_factor * range * |increment| of the next point (range: the larger). Each
  // point's distance from the line through its neighbours as |cross| / sqrt(length2) (length2 0: no such
  // line, never flat); points with both links joined estimate the noise (candidates).
  const double min_gap = config_.min_gap;
  const double gap_per_range = config_.gap_factor * sweep.absIncrement();
  // max(|x|, |y|) is never more than the range (as sqrt rounds it): a gap from it is never wider, so
  // within it the points are joined whatever the range; both tested, in a loop of arithmetic (vectorised).
  // 1 where b lies farther from a than both gaps, else 0: distance2 <= either squared gap, tested on the
  // bits (non-negative doubles order as their bits do).
  const auto fartherThanGaps = [&](std::size_t a, std::size_t b) -> std::uint64_t {
    const double dx = x[b] - x[a], dy = y[b] - y[a];
    const double distance2 = dx * dx + dy * dy;
    const double low_gap = min_gap + gap_per_range * std::max(scale[a], scale[b]);
    const double gap = min_gap + gap_per_range * std::max(range[a], range[b]);
    const std::uint64_t limit = bitCast<std::uint64_t>(std::max(low_gap * low_gap, gap * gap));
    return (limit - bitCast<std::uint64_t>(distance2)) >> 63;
  };
  // (the tests' bits kept in a double: a store that may alias the loads keeps GCC from carrying them from one
  // point to the next, which it does not vectorise)
  double* const farther = join_test_.data();
  for (std::size_t j = 0; j + 1 < n; ++j)
    farther[j] = bitCast<double>(fartherThanGaps(j, j + 1));
  for (std::size_t j = 0; j + 1 < n; ++j)
    joined[j] = has_next[j] & static_cast<unsigned char>(bitCast<std::uint64_t>(farther[j]) ^ 1u);
  joined[n - 1] = wraps_ && fartherThanGaps(n - 1, 0) == 0;
  const auto residualOf = [&](std::size_t p, std::size_t j, std::size_t q, bool linked) {
    const double ex = x[q] - x[p], ey = y[q] - y[p];
    const double l2 = ex * ex + ey * ey;
    cross_product[j] = linked && l2 != 0.0 ? ex * (y[j] - y[p]) - ey * (x[j] - x[p]) : kInfinity;
    length2[j] = l2;
    return linked && l2 != 0.0;
  };
  // Residuals (infinite without both neighbours: never flat) and the candidates, in loops of arithmetic
  // alone (vectorised).
  for (std::size_t j = 1; j + 1 < n; ++j) {
    const double ex = x[j + 1] - x[j - 1], ey = y[j + 1] - y[j - 1];
    cross_product[j] = ex * (y[j] - y[j - 1]) - ey * (x[j] - x[j - 1]);
    length2[j] = ex * ex + ey * ey;
  }
  unsigned char* const line = line_.data();
  for (std::size_t j = 1; j + 1 < n; ++j) {  // (length2 >= +0: its bits are 0 only for 0)
    const unsigned char nonzero =
        static_cast<unsigned char>((bitCast<std::uint64_t>(length2[j]) + kMaxInt64) >> 63);
    const unsigned char is_line = has_next[j - 1] & has_next[j] & nonzero;
    line[j] = is_line;
    cross_product[j] = is_line ? cross_product[j] : kInfinity;
  }
  std::size_t count = 0;
  for (std::size_t j = 1; j + 1 < n; ++j) {
    const unsigned char is_candidate = joined[j - 1] & joined[j] & line[j];
    candidate[j] = is_candidate;
    count += is_candidate;
  }
  cross_product[0] = cross_product[n - 1] = kInfinity;
  length2[0] = length2[n - 1] = 0.0;
  candidate[0] = candidate[n - 1] = 0;
  if (wraps_) {
    candidate[n - 1] = residualOf(n - 2, n - 1, 0, has_next[n - 2]) && joined[n - 2] && joined[n - 1];
    candidate[0] = residualOf(n - 1, 0, 1, has_next[0]) && joined[n - 1] && joined[0];
    count += candidate[n - 1] + candidate[0];
  }
  candidate_count_ = count;
}

LIDAR_DESKEW_AVX2_CLONES void ScanRebinner::classifyLinks() {
  const std::size_t n = x_.size();
  // The scan's own noise: the median distance from its neighbours' line of every stride-th point within
  // one contour.
  const std::size_t candidate_count = candidate_count_;
  const std::size_t stride = std::max<std::size_t>(1, candidate_count / kNoiseSampleSize);
  noise_sample_.resize((candidate_count + stride - 1) / stride);
  // Every stride-th candidate in point order, by words of 8 candidate bytes (0 or 1): their sum skips a
  // word, or finds a word of 8 candidates' k-th directly.
  const unsigned char* const candidate = candidate_.data();
  std::size_t rank = 0, take = 0, k = 0;  // candidates before `word`, the next one sampled
  std::uint32_t histogram[kNoiseBuckets] = {};    // how many residuals in each noiseBucket()
  unsigned char bucket_of[2 * kNoiseSampleSize];  // each residual's (at most 2 kNoiseSampleSize of them)
  std::size_t lowest = kNoiseBuckets - 1;         // the first bucket that holds one
  for (std::size_t word = 0; take < candidate_count; word += 8) {
    std::uint64_t bytes;
    std::memcpy(&bytes, candidate + word, sizeof bytes);
    const std::size_t in_word = static_cast<std::size_t>((bytes * 0x0101010101010101u) >> 56);
    for (; take < rank + in_word; take += stride) {
      std::size_t j = word + (take - rank);
      if (in_word < 8) {
        j = word;
        for (std::size_t seen = candidate[j]; seen <= take - rank; seen += candidate[j])
          ++j;
      }
      const double residual = std::abs(cross_[j]) / std::sqrt(length2_[j]);
      noise_sample_[k++] = residual;
      const std::size_t bucket = noiseBucket(residual);
      bucket_of[k - 1] = static_cast<unsigned char>(bucket);
      lowest = std::min(lowest, bucket);
      ++histogram[bucket];
    }
    rank += in_word;
  }
  // (a NaN residual, 0/0, falls in the last bucket: looked for only when that bucket holds any)
  const bool any_nan =
      histogram[kNoiseBuckets - 1] > 0 &&
      std::any_of(noise_sample_.begin(), noise_sample_.end(), [](double r) { return std::isnan(r); });
  // The median: what nth_element puts in the middle, the same value found without its branches (from
  // the last scan's, as the first pivot) unless a residual is NaN (0/0), which the selection does not order.
  double median = 0.0;
  if (!noise_sample_.empty()) {
    const auto middle = noise_sample_.begin() + static_cast<std::ptrdiff_t>(noise_sample_.size() / 2);
    if (any_nan) {
      std::nth_element(noise_sample_.begin(), middle, noise_sample_.end());
      median = *middle;
    } else {
      // The bucket that holds it (those before hold the smaller residuals, those after the larger), then
      // the median among that bucket's residuals alone: the same value, from a few of them.
      const std::size_t middle_rank = noise_sample_.size() / 2;
      std::size_t bucket = lowest, before = 0;
      for (; before + histogram[bucket] <= middle_rank; ++bucket)
        before += histogram[bucket];
      // (found by memchr: a few of the sample)
      const std::size_t count = histogram[bucket];
      noise_bucket_.resize(count);
      double* const in_bucket = noise_bucket_.data();
      const unsigned char* found = bucket_of;
      for (std::size_t i = 0; i < count; ++i, ++found) {
        found = static_cast<const unsigned char*>(
            std::memchr(found, static_cast<int>(bucket),
                        noise_sample_.size() - static_cast<std::size_t>(found - bucket_of)));
        in_bucket[i] = noise_sample_[static_cast<std::size_t>(found - bucket_of)];
      }
      median = detail::kthSmallest(
          count, middle_rank - before, [in_bucket](std::size_t i) { return in_bucket[i]; }, noise_select_,
          noise_median_);
    }
  }
  flat_tolerance_ = kFlatToleranceFloor + kFlatToleranceMedians * median;
  // Flat: within the tolerance of the line through its neighbours (an infinite cross: no such line); a
  // surface: joined, one end flat. The other neighbours wait for classifyRareLinks() (kPending). Loops of
  // arithmetic on doubles, then on bytes (vectorised).
  const double tolerance2 = flat_tolerance_ * flat_tolerance_;
  flat_.resize(n);
  link_.resize(n);
  if (n == 0)
    return;
  unsigned char* const flat = flat_.data();
  const double* const cross_product = cross_.data();
  const double* const length2 = length2_.data();
  for (std::size_t j = 0; j < n; ++j)
    flat[j] = cross_product[j] * cross_product[j] <= tolerance2 * length2[j];
  const unsigned char* const joined = joined_.data();
  const unsigned char* const has_next = has_next_.data();
  unsigned char* const link = reinterpret_cast<unsigned char*>(link_.data());  // (bytes: 0 or 1 each)
  constexpr auto kSurface = static_cast<unsigned char>(Link::kSurface);
  constexpr auto kPending = static_cast<unsigned char>(Link::kPending);
  static_assert(static_cast<unsigned char>(Link::kNone) == 0, "kNone is the byte 0");
  const auto classify = [&](std::size_t j, unsigned char flat_q) {
    const unsigned char surface = joined[j] & (flat[j] | flat_q);
    link[j] = static_cast<unsigned char>(surface * kSurface + (has_next[j] & (surface ^ 1u)) * kPending);
  };
  for (std::size_t j = 0; j + 1 < n; ++j)
    classify(j, flat[j + 1]);
  classify(n - 1, flat[0]);  // the full circle's link (has_next: only then)
}

void ScanRebinner::classifyRareLinks(const BinSweep& sweep) {
  const std::size_t n = x_.size();
  corner_x_.resize(n);
  corner_y_.resize(n);
  Link* const link = link_.data();
  const auto findPending = [&](std::size_t from) {  // the next kPending link from `from`, or n (memchr)
    const void* found = from < n ? std::memchr(link + from, static_cast<int>(Link::kPending), n - from) : nullptr;
    return found ? static_cast<std::size_t>(static_cast<const Link*>(found) - link) : n;
  };
  for (std::size_t j = findPending(0); j < n; j = findPending(j + 1)) {
    const std::size_t q = next(j);
    // One of them flat (the line through its neighbours holds the other) and, a wall seen at a grazing
    // angle, its points farther apart than the gap: nearly joined.
    if ((flat_[j] || flat_[q]) && !joined_[j] && nearlyJoined(j, q, sweep)) {
      link[j] = Link::kSurface;
      continue;
    }
    // A corner: its three links joined; or, in a scan with little noise, a wall at a grazing angle (its
    // points farther apart than the gap): nearly joined, and a wall's line nearly joined only where a
    // third point confirms it (`confirm` flat: on the line through its neighbours).
    const auto close = [&](std::size_t a, std::size_t b, std::size_t confirm) {
      return joined_[a] || (nearlyJoined(a, b, sweep) && (confirm == kNoPoint || flat_[confirm]));
    };
    const std::size_t p = previous(j), r = next(q);
    if (p != kNoPoint && r != kNoPoint && close(j, q, kNoPoint) && close(p, j, p) && close(q, r, r) &&
        findCorner(p, j, q, r, corner_x_[j], corner_y_[j])) {
      link[j] = Link::kCorner;
      continue;
    }
    link[j] = Link::kStep;
  }
}

std::size_t ScanRebinner::next(std::size_t j) const {
  if (!has_next_[j])
    return kNoPoint;
  return j + 1 == x_.size() ? 0 : j + 1;
}

std::size_t ScanRebinner::previous(std::size_t j) const {
  const std::size_t candidate = j > 0 ? j - 1 : x_.size() - 1;
  return has_next_[candidate] && (j > 0 || wraps_) ? candidate : kNoPoint;
}

double ScanRebinner::rangeOf(std::size_t j) const {
  return range_[j];
}

double ScanRebinner::bearingOf(std::size_t j) const {
  return fastAtan2(y_[j], x_[j]);
}

ScanRebinner::Link ScanRebinner::resolveStep(std::size_t j, const BinSweep& sweep) {
  // A waiting link is a depth step when its farther point continues a surface on its other side.
  const std::size_t q = next(j);
  const bool far_is_next = rangeOf(q) > rangeOf(j);
  const std::size_t far_side = far_is_next ? q : previous(j);
  const bool far_continues = far_side != kNoPoint && link_[far_side] == Link::kSurface;
  if (!far_continues)
    return joined_[j] ? Link::kChord : Link::kNone;
  const bool adjacent =
      std::abs(wrapDelta(bearingOf(q) - bearingOf(j))) <= kMaxStepBins * sweep.absIncrement();
  if (!adjacent || std::abs(rangeOf(q) - rangeOf(j)) <= flat_tolerance_ ||
      !continuationIsSure(far_is_next ? j : q, far_is_next ? q : j, far_is_next ? next(q) : previous(j))) {
    return joined_[j] ? Link::kChord : Link::kNone;
  }
  return Link::kStep;
}

LIDAR_DESKEW_AVX2_CLONES void ScanRebinner::traceContours(const Points& points, const BinSweep& sweep) {
  const std::size_t n = x_.size();
  const double abs_increment = sweep.absIncrement();
  // Precise enough that a guess, not the noise, would be the error: guesses are left out (kGuessBudget).
  const bool precise = flat_tolerance_ <= kStepErrorBudget;
  const auto continues = [](Link link) { return link != Link::kNone && link != Link::kStep; };
  bool left_continues = false;  // the link of j - 1 (resolved) continues a contour
  ends_.clear();
  if (n > 0 && previous(0) == kNoPoint)
    offerOwnRay(0, points);  // no link before it
  // Plain pointers and locals for the common case: a surface whose ends lie between two consecutive rays
  // (neither on them): it meets the one ray between.
  const bool running = running_, with_intensities = with_intensities_;
  const Link* const link = link_.data();
  const std::int32_t* const position = position_.data();
  const double* const x = x_.data();
  const double* const y = y_.data();
  const double* const ray_cos = ray_cos_.data();
  const double* const ray_sin = ray_sin_.data();
  double* const best_range = best_range_.data();
  float* const best_intensity = best_intensity_.data();
  const unsigned char* const near_ray = near_ray_.data();
  const std::int32_t quarter = static_cast<std::int32_t>(ray_count_ / 4);
  // Link j -> q, a surface whose points lie between rays `first` and first + 1 and between first + step and
  // first + step + 1 (neither on them): the rays between, first + 1 .. first + step (step 0 to 2), meet it.
  const auto crossRaysBetween = [&](std::size_t j, std::size_t q, std::int32_t first, std::int32_t step) {
    const double ex = x[q] - x[j], ey = y[q] - y[j];
    const double numerator = x[j] * ey - y[j] * ex;
    const auto crossRay = [&](std::int32_t ray) {
      const double ray_x = ray_cos[ray], ray_y = ray_sin[ray];
      const double range = numerator / (ray_x * ey - ray_y * ex);
      if (range > 0.0 && range < best_range[ray]) {
        best_range[ray] = range;
        if (with_intensities) {
          best_intensity[ray] = intensityAt(x[j], y[j], ray_x, ray_y, range, numerator, points[j].intensity,
                                            points[q].intensity);
        }
      }
    };
    // (at most two rays, written out: as a loop GCC vectorises it, at a cost that 0 to 2 rays never repay)
    if (step > 0)
      crossRay(first + 1);
    if (step > 1)
      crossRay(first + 2);
  };
  const auto crossSurfaceLink = [&](std::size_t j, std::size_t q) {
    // The rays between the two positions meet the segment: one ray (a point on its position's ray or the
    // next meets it in its link on the other side, or offerOwnRay() there), or none or two where neither
    // point is near a ray (as crossSurface() finds, which takes the rest).
    const std::int32_t first = position[j], step = position[q] - first;
    const bool clear =
        step == 1 || ((step == 0) | (step == 2 && step <= quarter)) & !near_ray[j] & !near_ray[q];
    if (!(first >= 0 && clear))
      return crossSurface(j, q, points);
    crossRaysBetween(j, q, first, step);
    return true;
  };
  // Links begin .. end - 1, each with the one ray between its points' positions, those rays consecutive: a
  // loop of arithmetic (vectorised).
  const auto crossOneRayEach = [&](std::size_t begin, std::size_t end) {
    const std::size_t first_ray = static_cast<std::size_t>(position[begin] + 1);
    if (with_intensities) {
      crossConsecutiveRays(end - begin, x + begin, y + begin, intensity_.data() + begin, ray_cos + first_ray,
                           ray_sin + first_ray, best_range + first_ray, best_intensity + first_ray);
    } else {
      crossConsecutiveRays(end - begin, x + begin, y + begin, ray_cos + first_ray, ray_sin + first_ray,
                           best_range + first_ray);
    }
  };
  // What a run of surfaces does with link j, by running bin positions (positions are rays or kNoPosition:
  // one more than the last point's is a ray), in a loop of arithmetic on bytes (vectorised):
  // kOneRay: its points' positions are consecutive rays, runs of them crossOneRayEach() takes (found by
  // nextSpecial()); kNoRay, kTwoRays: its points lie between the same two rays or two rays apart, neither
  // near a ray, crossRaysBetween() (the common cases of crossSurfaceLink()); kOtherSurface: the rest,
  // crossSurfaceLink(), and always the last point's; kNotSurface: the run ends.
  constexpr unsigned char kOneRay = 0, kNoRay = 1, kTwoRays = 2, kOtherSurface = 3, kNotSurface = 4;
  static_assert(kNotSurface - 1 - 3 == kOneRay && kNotSurface - 1 - 2 == kNoRay &&
                    kNotSurface - 1 - 1 == kTwoRays && kNotSurface - 1 == kOtherSurface,
                "run_kind's arithmetic below");
  unsigned char* const run_kind = run_kind_.data();
  if (running && n > 0) {
    const unsigned char two_rays_clear = 2 <= quarter;
    for (std::size_t j = 0; j + 1 < n; ++j) {
      const std::int32_t step = position[j + 1] - position[j];
      const unsigned char surface = link[j] == Link::kSurface;
      // (a point without a position is near a ray: locatePoints())
      const unsigned char clear = (near_ray[j] | near_ray[j + 1]) ^ 1u;
      const unsigned char one = step == 1, none = (step == 0) & clear;
      const unsigned char two = (step == 2) & two_rays_clear & clear;
      run_kind[j] = static_cast<unsigned char>(kNotSurface - surface * (1u + 3u * one + 2u * none + two));
    }
    run_kind[n - 1] = link[n - 1] == Link::kSurface ? kOtherSurface : kNotSurface;
  }
  // The first link from `from` that is not kOneRay (there is one: the last point's), by words of 8 bytes
  // (run_kind_ is padded to whole words past the last point): runs are short, a library call costs more.
  const auto nextSpecial = [run_kind](std::size_t from) {
#if defined(__GNUC__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    for (;; from += 8) {
      std::uint64_t word;
      std::memcpy(&word, run_kind + from, sizeof word);
      if (word != 0)
        return from + static_cast<std::size_t>(__builtin_ctzll(word) >> 3);  // its first non-zero byte
    }
#else
    while (run_kind[from] == kOneRay)
      ++from;
    return from;
#endif
  };
  for (std::size_t j = 0; j < n; ++j) {
    Link kind = link[j];
    if (kind == Link::kSurface && running) {
      // A run of surfaces, in one loop: each by running bin positions (the common cases inline), by bearing
      // where they cannot.
      if (j > 0 && !left_continues)
        ends_.push_back(j);
      left_continues = true;
      for (;; ++j) {
        // links j .. last - 1 have one ray each, consecutive
        const std::size_t last = nextSpecial(j);
        if (last > j)  // (a run of none: nothing to set up)
          crossOneRayEach(j, last);
        j = last;
        const unsigned char run = run_kind[j];
        if (run == kNotSurface) {  // (not the run's first link: that is a surface)
          --j;
          break;
        }
        if (run == kTwoRays) {
          crossRaysBetween(j, j + 1, position[j], 2);
        } else if (run == kOtherSurface) {
          const std::size_t q = j + 1 == n ? 0 : j + 1;
          if (!crossSurfaceLink(j, q)) {
            crossSegmentByBearing(x[j], y[j], bearingOf(j), points[j].intensity, x[q], y[q], bearingOf(q),
                                  points[q].intensity, sweep);
          }
        }
        if (j + 1 == n)
          break;
      }
      continue;
    }
    const std::size_t q = kind == Link::kNone ? kNoPoint : next(j);
    if (kind == Link::kStep) {
      kind = resolveStep(j, sweep);  // a step's far side is only compared with kSurface: order is free
      link_[j] = kind;
    }
    const bool segment =
        kind == Link::kSurface ||
        (kind == Link::kChord && !(precise && std::hypot(x_[q] - x_[j], y_[q] - y_[j]) > 2.0 * kGuessBudget));
    if (!segment && kind != Link::kCorner) {  // no crossing through its ends: a ray on one is its own
      offerOwnRay(j, points);
      if (q != kNoPoint)
        offerOwnRay(q, points);
    }
    if (segment) {
      // A segment (a chord longer than 2 kGuessBudget: its surface cannot be told, left empty). Less than
      // a quarter turn wide (so not through the sensor): by running bin positions.
      if (!(running_ && crossSurface(j, q, points))) {
        crossSegmentByBearing(x_[j], y_[j], bearingOf(j), points[j].intensity, x_[q], y_[q], bearingOf(q),
                              points[q].intensity, sweep);
      }
    } else if (kind == Link::kCorner) {
      crossCorner(points, j, q, sweep);
    } else if (kind == Link::kStep) {
      // The far contour's end segment continued behind the near point, over the bearings between.
      const bool far_is_next = rangeOf(q) > rangeOf(j);
      const std::size_t near = far_is_next ? j : q, far = far_is_next ? q : j;
      const std::size_t beyond = far_is_next ? next(q) : previous(j);
      const double delta = wrapDelta(bearingOf(far) - bearingOf(near));
      extendLine(points, far, x_[far] - x_[beyond], y_[far] - y_[beyond], kInfinity, rangeOf(near),
                 std::min(bearingOf(near), bearingOf(near) + delta), std::abs(delta), sweep, kMaxStepSlant,
                 false, rangeOf(far) + flat_tolerance_);
    }
    // Both links of point j are final now (point 0's left one, the full circle's last, comes last). A
    // link of j - 1 that continues a contour joins it to j.
    const bool right_continues = continues(kind);
    if (j > 0 && !(left_continues && right_continues))
      ends_.push_back(j);
    left_continues = right_continues;
  }
  if (n > 0) {
    const std::size_t p = previous(0);
    if (!(continues(p == kNoPoint ? Link::kNone : link_[p]) && continues(link_[0])))
      ends_.insert(ends_.begin(), 0);
  }
  // Contour ends: where a point continues a contour on one side only, or on neither (a lone point).
  for (const std::size_t j : ends_) {
    const std::size_t p = previous(j), q = next(j);
    const Link left = p == kNoPoint ? Link::kNone : link_[p];
    const Link right = q == kNoPoint ? Link::kNone : link_[j];
    const double half_bin = 0.5 * abs_increment;
    const auto endReach = [&](std::size_t a, std::size_t b) {
      return precise ? std::min(kGuessBudget, joinGap(a, b, abs_increment)) : joinGap(a, b, abs_increment);
    };
    if (!continues(left) && !continues(right)) {
      // Lone return: a facet facing the sensor.
      extendLine(points, j, -y_[j], x_[j], endReach(j, j), 0.0, bearingOf(j) - half_bin, abs_increment,
                 sweep);
      continue;
    }
    const bool from_left = continues(left);
    // Follow the end segment (from the neighbour, or the corner, towards j) for up to half a bin; the
    // near end of a step only into bins the far contour did not reach.
    const Link end = from_left ? right : left;
    const bool near_end_of_step = end == Link::kStep && rangeOf(j) < rangeOf(from_left ? q : p);
    const std::size_t neighbour = from_left ? p : q;
    const Link kept = from_left ? left : right;
    const std::size_t corner_of = from_left ? p : j;
    const double nx = kept == Link::kCorner ? corner_x_[corner_of] : x_[neighbour];
    const double ny = kept == Link::kCorner ? corner_y_[corner_of] : y_[neighbour];
    extendLine(points, j, x_[j] - nx, y_[j] - ny, endReach(j, neighbour), 0.0,
               bearingOf(j) - half_bin - kBearingError, abs_increment + 2.0 * kBearingError, sweep, 0.0,
               near_end_of_step);
  }
}

LIDAR_DESKEW_AVX2_CLONES void ScanRebinner::writeNearestCrossings(float no_return, RebinnedScan& out) {
  const std::size_t bin_count = rays_grid_.count;
  std::fill(best_range_.begin() + static_cast<std::ptrdiff_t>(bin_count), best_range_.end(), kInfinity);
  // Each bin converted (into scratch: a vector is zeroed before it is written, when `out` was moved from)
  // and left empty for the next scan, in a vectorised loop; then copied out. A bin is finite or +inf (no
  // crossing): converted alone when "no return" is +inf too.
  double* const best_range = best_range_.data();
  float* const ranges = converted_.data();
  if (no_return == std::numeric_limits<float>::infinity()) {
    for (std::size_t b = 0; b < bin_count; ++b) {
      ranges[b] = static_cast<float>(best_range[b]);
      best_range[b] = kInfinity;
    }
  } else {
    for (std::size_t b = 0; b < bin_count; ++b) {
      const double range = best_range[b];
      ranges[b] = range < kInfinity ? static_cast<float>(range) : no_return;
      best_range[b] = kInfinity;
    }
  }
  out.ranges.assign(ranges, ranges + bin_count);
  if (with_intensities_) {
    float* const best_intensity = best_intensity_.data();
    out.intensities.assign(best_intensity, best_intensity + bin_count);
    std::fill(best_intensity, best_intensity + bin_count, 0.0f);
  } else {
    out.intensities.clear();
  }
}

bool ScanRebinner::nearlyJoined(std::size_t a, std::size_t b, const BinSweep& sweep) {
  const double abs_increment = sweep.absIncrement();
  // the flat test is evidence of one surface only when the noise is small against the error budget
  if (flat_tolerance_ > kStepErrorBudget)
    return false;
  const double dx = x_[b] - x_[a], dy = y_[b] - y_[a];
  const double limit = kFlatJoinGaps * joinGap(a, b, abs_increment);
  return std::abs(wrapDelta(bearingOf(b) - bearingOf(a))) <= kMaxStepBins * abs_increment &&
         dx * dx + dy * dy <= limit * limit;
}

double ScanRebinner::joinGap(std::size_t a, std::size_t b, double abs_increment) const {
  return config_.min_gap + config_.gap_factor * std::max(rangeOf(a), rangeOf(b)) * abs_increment;
}

bool ScanRebinner::continuationIsSure(std::size_t near, std::size_t far, std::size_t beyond) {
  if (beyond == kNoPoint)
    return false;
  const double segment = std::hypot(x_[far] - x_[beyond], y_[far] - y_[beyond]);
  // [m] how far the continuation runs along a wall facing the sensor: to the near point's bearing
  const double run = rangeOf(far) * std::abs(wrapDelta(bearingOf(far) - bearingOf(near)));
  return segment > 0.0 && flat_tolerance_ * (1.0 + run / segment) <= kStepErrorBudget;
}

bool ScanRebinner::findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1, double& corner_x,
                              double& corner_y) const {
  const double ax = x_[a], ay = y_[a], bx = x_[b], by = y_[b];
  const double dax = ax - x_[a0], day = ay - y_[a0];  // along the wall before a, towards a
  const double dbx = x_[b1] - bx, dby = y_[b1] - by;  // along the wall after b, away from b
  const double denominator = cross(dax, day, dbx, dby);
  if (denominator == 0.0)
    return false;
  const double s = cross(bx - ax, by - ay, dbx, dby) / denominator;  // corner = a + s (dax, day)
  const double t = cross(bx - ax, by - ay, dax, day) / denominator;  // corner = b + t (dbx, dby)
  if (s < 0.0 || t > 0.0)
    return false;  // the walls would have to turn back before a or after b
  corner_x = ax + s * dax;
  corner_y = ay + s * day;
  const double side = cross(ax, ay, bx, by);
  if (cross(ax, ay, corner_x, corner_y) * side <= 0.0 || cross(corner_x, corner_y, bx, by) * side <= 0.0 ||
      corner_x * (ax + bx) + corner_y * (ay + by) <= 0.0) {
    return false;  // not between the two points' bearings
  }
  const double chord2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay);
  const double to_a2 = (corner_x - ax) * (corner_x - ax) + (corner_y - ay) * (corner_y - ay);
  const double to_b2 = (corner_x - bx) * (corner_x - bx) + (corner_y - by) * (corner_y - by);
  return to_a2 <= 4.0 * chord2 && to_b2 <= 4.0 * chord2;  // plausibly near both
}

void ScanRebinner::crossCorner(const Points& points, std::size_t j, std::size_t q, const BinSweep& sweep) {
  const float j_intensity = points[j].intensity, q_intensity = points[q].intensity;
  const double cx = corner_x_[j], cy = corner_y_[j];
  if (running_ && x_[j] * cx + y_[j] * cy > 0.0 && cx * x_[q] + cy * y_[q] > 0.0 && position_[j] >= 0 &&
      position_[q] >= 0) {
    const Rays rays = this->rays(sweep.absIncrement());
    const auto rayPoint = [&](std::size_t p) {
      const std::int32_t ray = position_[p];
      return RayPoint{x_[p],
                      y_[p],
                      ray,
                      rays.side(ray, x_[p], y_[p]),
                      rays.side(ray + 1, x_[p], y_[p]),
                      points[p].intensity};
    };
    RayPoint corner{cx, cy, -1, 0.0, 0.0, j_intensity};
    corner.ray = rays.locate(cx, cy, position_[j], corner.low, corner.high);
    if (corner.ray >= 0) {
      crossRays(rayPoint(j), corner);
      corner.intensity = q_intensity;
      crossRays(corner, rayPoint(q));
      return;
    }
  }
  const double corner_bearing = fastAtan2(cy, cx);
  crossSegmentByBearing(x_[j], y_[j], bearingOf(j), j_intensity, cx, cy, corner_bearing, j_intensity, sweep);
  crossSegmentByBearing(cx, cy, corner_bearing, q_intensity, x_[q], y_[q], bearingOf(q), q_intensity, sweep);
}

void ScanRebinner::crossSegmentByBearing(double ax, double ay, double a_bearing, float a_intensity, double bx,
                                         double by, double b_bearing, float b_intensity,
                                         const BinSweep& sweep) {
  const double delta = wrapDelta(b_bearing - a_bearing);
  if (std::abs(delta) >= M_PI - 1e-6)
    return;  // passes through the sensor: not a visible surface
  const double ex = bx - ax, ey = by - ay;
  sweep.forEachBinIn(std::min(a_bearing, a_bearing + delta) - kBearingError,
                     std::abs(delta) + 2.0 * kBearingError, [&](std::size_t bin) {
                       const double ray_x = ray_cos_[bin], ray_y = ray_sin_[bin];
                       const double denominator = cross(ray_x, ray_y, ex, ey);
                       if (denominator == 0.0)
                         return;
                       const double u = cross(ax, ay, ray_x, ray_y) / denominator;
                       if (u < -kVertexTolerance || u > 1.0 + kVertexTolerance)
                         return;
                       const double range = cross(ax, ay, ex, ey) / denominator;
                       if (range <= 0.0)
                         return;
                       offer(bin, range, static_cast<float>((1.0 - u) * a_intensity + u * b_intensity));
                     });
}

void ScanRebinner::extendLine(const Points& points, std::size_t p, double dx, double dy, double reach,
                              double min_range, double low, double width, const BinSweep& sweep,
                              double max_slant, bool only_empty, double max_range) {
  const double px = x_[p], py = y_[p];
  const double direction_norm = std::sqrt(dx * dx + dy * dy);
  if (direction_norm == 0.0)
    return;
  sweep.forEachBinIn(low, width, [&](std::size_t bin) {
    if (only_empty && best_range_[bin] != kInfinity)
      return;
    const double ray_x = ray_cos_[bin], ray_y = ray_sin_[bin];
    const double denominator = cross(ray_x, ray_y, dx, dy);
    if (denominator == 0.0)
      return;
    const double u = cross(px, py, ray_x, ray_y) / denominator;
    const double along = std::abs(u) * direction_norm;  // [m] from p
    if (along > reach)
      return;
    const double range = cross(px, py, dx, dy) / denominator;
    if (range <= 0.0 || range < min_range || range > max_range)
      return;
    // slant: how far along the line per metre sideways (of the ray's angle from p, at p's range)
    if (max_slant > 0.0 && along > max_slant * std::abs(cross(px, py, ray_x, ray_y)) * 1.0000001)
      return;
    offer(bin, range, points[p].intensity);
  });
}

void ScanRebinner::offer(std::size_t bin, double range, float intensity) {
  const double value = range;
  if (value < best_range_[bin]) {
    best_range_[bin] = value;
    if (with_intensities_)
      best_intensity_[bin] = intensity;
  }
}

}  // namespace lidar_deskew::core
