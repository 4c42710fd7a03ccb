// Test support: core::ScanRebinner as it was before the rewrite of issue 35, frozen (see
// reference_rebin.h): a copy of src/core/rebin.cpp at that commit, less what the core keeps
// (RebinConfig::validate, noReturnValue); fastAtan2 is the core's own (src/core/fast_atan2.h).
#include "support/reference_rebin.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "../../src/core/fast_atan2.h"

namespace lidar_deskew::test {
using core::AngleGrid;
using core::DeskewedPoint;
using core::DeskewedScan;
using core::InvalidInput;
using core::RebinConfig;
using core::RebinnedScan;

namespace {

constexpr double kTwoPi = 2.0 * M_PI;
/// Tolerance on the segment parameter of a crossing: a ray through a contour's vertex meets it.
constexpr double kVertexTolerance = 1e-9;

inline double cross(double ax, double ay, double bx, double by) {
  return ax * by - ay * bx;
}

/// [rad] bearings are off by at most this: intervals of bins are widened by it (the crossing test is exact).
constexpr double kBearingError = 2.0 * core::detail::kFastAtan2Error;
using core::detail::fastAtan2;

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
class ReferenceRebinner::BinSweep {
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

ReferenceRebinner::ReferenceRebinner(const RebinConfig& config) : config_(config) {
  config_.validate();
}

namespace {

/// A point's running bin position moves at most this many rays from its hint before it is found again
/// from the point's bearing (a contour start after a long gap, a fold-over).
constexpr int kMaxWalk = 16;
/// Running bin positions need the rays of the whole circle; grids finer than this many rays per turn
/// (or wider than a turn) are swept by bearing instead.
constexpr double kMaxRunningRays = 1 << 16;
constexpr std::size_t kUnknown = static_cast<std::size_t>(-1);
/// Rays::locate() reads up to this many rays past its hint (the last ray at most).
constexpr std::size_t kRayPadding = 3;
/// A quantity decided by a squared comparison is decided exactly (as sqrt and division would) when it is
/// this close, relatively, to its threshold.
constexpr double kSquaredMargin = 1e-9;

}  // namespace

/// The rays of the grid as running bin positions see them, copied into locals by the per-point loops (a
/// store through a scratch array could alias a member, so members would be loaded again every point).
struct ReferenceRebinner::Rays {
  const double* side_cos;  // direction_ times each ray's direction: side() without a multiplication
  const double* side_sin;
  std::size_t count;  // ray_count_
  double angle_min;   // [rad] of the grid
  double abs_increment;
  double direction;

  /// [m] how far the point (px, py) lies past ray `ray` in the grid's direction (negative: before it):
  /// direction * cross(ray, p) with the sign folded into the ray, the same value (at most -0 for +0,
  /// which every use compares with 0 alike).
  double side(std::size_t ray, double px, double py) const {
    return cross(side_cos[ray], side_sin[ray], px, py);
  }
  /// The ray after `ray` and the one before it, the rays taken round (the last ray's next is the first).
  std::size_t next(std::size_t ray) const { return ray + 1 == count ? 0 : ray + 1; }
  std::size_t previous(std::size_t ray) const { return ray == 0 ? count - 1 : ray - 1; }

  /// The running bin position of (px, py): the ray it lies on or past whose next ray it lies before,
  /// walking from `ray`, with side() of both (`low` >= 0, `high` < 0); kUnknown when not within
  /// kMaxWalk rays of it.
  [[gnu::always_inline]] std::size_t walk(std::size_t ray, double px, double py, double& low,
                                          double& high) const {
    double at = side(ray, px, py);
    for (int step = 0; step < kMaxWalk; ++step) {
      if (at < 0.0) {  // before this ray: one back
        ray = previous(ray);
        at = side(ray, px, py);
        continue;
      }
      const std::size_t after = next(ray);
      const double at_after = side(after, px, py);
      if (at_after < 0.0) {
        low = at;
        high = at_after;
        return ray;
      }
      ray = after;
      at = at_after;
    }
    return kUnknown;
  }

  /// As walk(), from `hint` (the ray at or after it, tried first) and, when too far from it, from the
  /// point's bearing (locateFar, out of line).
  [[gnu::always_inline]] std::size_t locate(double px, double py, std::size_t hint, double& low,
                                            double& high) const {
    // Most points lie on or past the previous point's ray and before the one after next: two rays tried.
    // A scan that turned with the sensor spreads its points over more than its grid, so every few points
    // one lies a ray further: three, where walk() from the hint would go forward too (the point on or past
    // the hint's ray) and so find the same.
    // The ray arrays go on for kRayPadding rays past the last (copies of the first), so the rays after
    // the hint are read without taking them round; only a position returned is.
    const double at_next = side(hint + 1, px, py);
    if (at_next >= 0.0) {
      const double at_after = side(hint + 2, px, py);
      if (at_after < 0.0) {
        low = at_next;
        high = at_after;
        return next(hint);
      }
      const double at_further = side(hint + 3, px, py);
      if (at_further < 0.0 && side(hint, px, py) >= 0.0) {
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

  [[gnu::noinline]] std::size_t locateFar(double px, double py, std::size_t hint, double& low,
                                          double& high) const {
    std::size_t found = walk(hint, px, py, low, high);
    if (found != kUnknown)
      return found;
    // Far from the hint: start again from the point's bearing (within a ray of its position).
    const double offset = wrapToTurn(direction * (fastAtan2(py, px) - angle_min));
    const double ray = std::floor(offset / abs_increment);
    found = walk(std::min(static_cast<std::size_t>(std::max(ray, 0.0)), count - 1), px, py, low, high);
    if (found != kUnknown)
      return found;
    for (std::size_t candidate = 0; candidate < count; ++candidate) {  // never needed so far
      const double at = side(candidate, px, py);
      const double after = side(next(candidate), px, py);
      if (at >= 0.0 && after < 0.0) {
        low = at;
        high = after;
        return candidate;
      }
    }
    return kUnknown;
  }
};

ReferenceRebinner::Rays ReferenceRebinner::rays() const {
  return {side_cos_.data(),
          side_sin_.data(),
          ray_count_,
          static_cast<double>(rays_grid_.angle_min),
          std::abs(static_cast<double>(rays_grid_.angle_increment)),
          direction_};
}

/// The rays and the bins' nearest crossings, copied into locals for the per-link loops (a store through
/// a byte, a resolved link, may alias any member: members would be loaded again every link).
struct ReferenceRebinner::Bins {
  const double* ray_cos;  // unit direction of every ray
  const double* ray_sin;
  double* best_range;  // [m] per bin
  float* best_intensity;
  const DeskewedPoint* points;  // the corrected points, for their intensities
  std::size_t bin_count;
  std::size_t ray_count;
  bool with_intensities;

  /// The segment (ax, ay) -> (bx, by), less than a quarter turn wide, its ends at running positions
  /// a_ray and b_ray (with their side() values): offers the rays between them, and the ray at or before
  /// the earlier end and the one after the later end where that end lies on it (within the vertex
  /// tolerance). Its intensity runs from point a_point's to point b_point's (read only where a bin
  /// takes it).
  [[gnu::always_inline]] void crossRays(double ax, double ay, std::size_t a_ray, double a_low, double a_high,
                                        std::size_t a_point, double bx, double by, std::size_t b_ray,
                                        double b_low, double b_high, std::size_t b_point) const {
    const double ex = bx - ax, ey = by - ay;
    const double numerator = cross(ax, ay, ex, ey);
    // The crossing of one ray, tested as crossSegmentByBearing tests it; u (= along / denominator) plainly
    // within [0, 1] needs no division, plainly outside it (by twice the vertex tolerance) is rejected. A
    // ray parallel to the segment (denominator 0) needs no test of its own: along 0 gives a range of
    // +-inf or NaN, which no bin keeps; other alongs are outside [0, 0].
    const auto crossRay = [&](std::size_t ray) {
      if (ray >= bin_count)
        return;  // past the grid's last bin
      const double ray_x = ray_cos[ray], ray_y = ray_sin[ray];
      const double denominator = cross(ray_x, ray_y, ex, ey);
      const double along = cross(ax, ay, ray_x, ray_y);
      const double magnitude = std::abs(denominator), signed_along = denominator < 0.0 ? -along : along;
      if (!(signed_along >= 0.0 && signed_along <= magnitude)) {
        if (signed_along < -2.0 * kVertexTolerance * magnitude ||
            signed_along > (1.0 + 2.0 * kVertexTolerance) * magnitude) {
          return;
        }
        const double u = along / denominator;
        if (u < -kVertexTolerance || u > 1.0 + kVertexTolerance)
          return;
      }
      const double range = numerator / denominator;
      if (range <= 0.0 || !(range < best_range[ray]))
        return;
      best_range[ray] = range;
      if (with_intensities) {
        const double u = along / denominator;
        best_intensity[ray] =
            static_cast<float>((1.0 - u) * points[a_point].intensity + u * points[b_point].intensity);
      }
    };
    // Rays strictly between the two positions cross the segment; the ray at or before the earlier point
    // and the one after the later point only when that point lies (almost) on it: within the vertex
    // tolerance of |e| (|cross(ray, point)| is the point's distance from the ray).
    const double near_ray = 2.0 * kVertexTolerance * (std::abs(ex) + std::abs(ey));
    std::size_t forward = b_ray >= a_ray ? b_ray - a_ray : b_ray + ray_count - a_ray;
    std::size_t first = a_ray;
    bool test_first = a_low <= near_ray, test_last = -b_high <= near_ray;
    if (forward == 0) {
      test_first = test_first || b_low <= near_ray;
      test_last = test_last || -a_high <= near_ray;
    } else if (forward > ray_count / 2) {  // b before a in the grid's direction
      forward = ray_count - forward;
      first = b_ray;
      test_first = b_low <= near_ray;
      test_last = -a_high <= near_ray;
    }
    // One loop over them all, so the crossing test is inlined once; the rays taken round only where they
    // pass the last one.
    std::size_t ray = first + (test_first ? 0 : 1);
    if (ray == ray_count)
      ray = 0;
    const std::size_t count = forward + (test_first ? 1 : 0) + (test_last ? 1 : 0);
    if (ray + count <= ray_count) {
      for (const std::size_t end = ray + count; ray < end; ++ray)
        crossRay(ray);
      return;
    }
    for (std::size_t k = 0; k < count; ++k) {
      crossRay(ray);
      ray = ray + 1 == ray_count ? 0 : ray + 1;
    }
  }
};

ReferenceRebinner::Bins ReferenceRebinner::bins(const Points& points) {
  return {ray_cos_.data(), ray_sin_.data(),    best_range_.data(), best_intensity_.data(),
          points.data(),   best_range_.size(), ray_count_,         with_intensities_};
}

void ReferenceRebinner::updateRays(const AngleGrid& grid) {
  if (ray_cos_.size() == ray_count_ && rays_grid_.count == grid.count &&
      rays_grid_.angle_min == grid.angle_min && rays_grid_.angle_increment == grid.angle_increment &&
      best_range_.size() == grid.count) {
    return;
  }
  rays_grid_ = grid;
  const double abs_increment = std::abs(static_cast<double>(grid.angle_increment));
  // Rays past the grid's last bin up to a full turn (not offered) let a bin position run modulo
  // ray_count_ around the circle.
  const double rays_per_turn = abs_increment > 0.0 ? (kTwoPi - 1e-9) / abs_increment : kInfinity;
  running_ = grid.count > 1 && rays_per_turn <= kMaxRunningRays &&
             abs_increment * static_cast<double>(grid.count - 1) < kTwoPi - 1e-9;
  ray_count_ =
      running_ ? std::max(grid.count, static_cast<std::size_t>(std::floor(rays_per_turn)) + 1) : grid.count;
  direction_ = grid.angle_increment < 0.0f ? -1.0 : 1.0;
  ray_cos_.resize(ray_count_);
  ray_sin_.resize(ray_count_);
  side_cos_.resize(ray_count_ + kRayPadding);
  side_sin_.resize(ray_count_ + kRayPadding);
  for (std::size_t b = 0; b < ray_count_; ++b) {
    const double angle = static_cast<double>(grid.angle_min) + static_cast<double>(b) * grid.angle_increment;
    ray_cos_[b] = std::cos(angle);
    ray_sin_[b] = std::sin(angle);
    side_cos_[b] = direction_ * ray_cos_[b];
    side_sin_[b] = direction_ * ray_sin_[b];
  }
  for (std::size_t b = ray_count_; b < ray_count_ + kRayPadding && ray_count_ > 0; ++b) {
    side_cos_[b] = side_cos_[b % ray_count_];
    side_sin_[b] = side_sin_[b % ray_count_];
  }
  // Every bin starts with no crossing; writeNearestCrossings() leaves them so for the next scan.
  best_range_.assign(grid.count, kInfinity);
  best_intensity_.assign(grid.count, 0.0f);
}

void ReferenceRebinner::rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return,
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
  findFlatPoints();
  classifyLinks(sweep);
  bins_in_use_ = true;
  traceContours(corrected.points, sweep);
  writeNearestCrossings(no_return, out);
  bins_in_use_ = false;
}

void ReferenceRebinner::readPoints(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  // Sizes only change with the scan's return count: no allocation and no fill per scan but for the two
  // polar caches below.
  point_.resize(point_count);
  joined_.resize(point_count);
  candidates_.resize(point_count);
  // Ranges and bearings only where a rule needs them (see rangeOf, bearingOf); 0 (all bits clear, one
  // memset) marks "not yet".
  range_.resize(point_count);
  bearing_.resize(point_count);
  if (point_count > 0) {
    std::memset(range_.data(), 0, point_count * sizeof(double));
    std::memset(bearing_.data(), 0, point_count * sizeof(double));
  }
  // Plain pointers: stores through the char flags would otherwise reload every vector's data.
  PointState* const point = point_.data();
  char* const joined = joined_.data();
  std::uint32_t* const candidates = candidates_.data();
  std::size_t candidate_count = 0;
  const double abs_increment = sweep.absIncrement();
  const double min_gap = config_.min_gap, gap_factor = config_.gap_factor;
  const auto isJoined = [&](std::size_t a, std::size_t b) {
    const double dx = point[b].x - point[a].x, dy = point[b].y - point[a].y;
    const double distance2 = dx * dx + dy * dy;
    // max(|x|, |y|) is never more than the range (as sqrt rounds it): a gap from it is never wider than
    // joinGap, so within it the points are joined without a square root.
    const double low = std::max(std::max(std::abs(point[a].x), std::abs(point[a].y)),
                                std::max(std::abs(point[b].x), std::abs(point[b].y)));
    const double low_limit = min_gap + gap_factor * low * abs_increment;
    if (distance2 <= low_limit * low_limit)
      return true;
    const double limit = joinGap(a, b, abs_increment);
    return distance2 <= limit * limit;
  };
  // A point's distance from the line through its neighbours (p, point[j].next) is |cross| / length; kept as
  // cross and length^2 (no square root, no division), exactly only for the noise sample and near the
  // tolerance (findFlatPoints). Points with both links joined estimate the noise (candidates).
  const auto measureResidual = [&](std::size_t j, std::size_t p) {
    const std::size_t q = point[j].next;
    point[j].length2 = 0.0;  // no neighbours' line: never flat
    if (p == kNoPoint || q == kNoPoint)
      return false;
    const double ex = point[q].x - point[p].x, ey = point[q].y - point[p].y;
    point[j].cross = cross(ex, ey, point[j].x - point[p].x, point[j].y - point[p].y);
    point[j].length2 = ex * ex + ey * ey;
    return point[j].length2 != 0.0 && joined[p] && joined[j];
  };
  const bool running = running_;
  const Rays rays = this->rays();
  std::size_t hint = 0;
  // The two points before j, carried in registers (stores through the byte flags would reload them).
  double x1 = 0.0, y1 = 0.0, x0 = 0.0, y0 = 0.0;
  double low1 = 0.0;  // max(|x1|, |y1|)
  std::uint32_t beam1 = 0;
  bool linked0 = false, joined0 = false;  // the link from the point before j - 1 to j - 1
  bool finite = true;                     // every point so far finite (checked once, after the loop)
  // One pass: point j read (and its running bin position found from the previous point's); the link
  // from point j - 1 to j; and point j - 1's distance from the line through its neighbours.
  for (std::size_t j = 0; j < point_count; ++j) {
    const double px = points[j].position.x(), py = points[j].position.y();
    point[j].x = px;
    point[j].y = py;
    const double abs_x = std::abs(px), abs_y = std::abs(py);
    // A sum that is not <= DBL_MAX: a coordinate is not finite (or both are huge; the check below tells).
    finite &= abs_x + abs_y <= std::numeric_limits<double>::max();
    if (running) {
      point[j].position = rays.locate(px, py, hint, point[j].side_low, point[j].side_high);
      if (point[j].position != kUnknown)
        hint = point[j].position;
    }
    // max(|x|, |y|) is never more than the range (as sqrt rounds it): a gap from it is never wider than
    // joinGap, so within it the points are joined without a square root.
    const double low = std::max(abs_x, abs_y);
    const std::uint32_t beam = points[j].beam_index;
    if (j > 0) {
      const std::size_t i = j - 1;
      const bool neighbours = beam == beam1 + 1;
      point[i].next = neighbours ? j : kNoPoint;
      bool joined_i = false;
      if (neighbours) {
        const double dx = px - x1, dy = py - y1;
        const double distance2 = dx * dx + dy * dy;
        const double low_limit = min_gap + gap_factor * std::max(low1, low) * abs_increment;
        if (distance2 <= low_limit * low_limit) {
          joined_i = true;
        } else {
          const double limit = joinGap(i, j, abs_increment);
          joined_i = distance2 <= limit * limit;
        }
      }
      joined[i] = joined_i;
      // Point i's distance from the line through i - 1 and j, computed whether or not they are its
      // neighbours (branch-free): length2 0 says "no neighbours' line, never flat". Point 0's previous
      // point, on a full circle the last, is not known yet: measured again below.
      const double ex = px - x0, ey = py - y0;
      const double l2 = ex * ex + ey * ey;
      point[i].cross = cross(ex, ey, x1 - x0, y1 - y0);
      point[i].length2 = linked0 && neighbours ? l2 : 0.0;
      // joined0 is false for i == 0 (and implies linked0); joined_i implies neighbours.
      candidates[candidate_count] = static_cast<std::uint32_t>(i);
      candidate_count += joined0 && joined_i && l2 != 0.0;
      linked0 = neighbours;
      joined0 = joined_i;
    }
    x0 = x1;
    y0 = y1;
    x1 = px;
    y1 = py;
    low1 = low;
    beam1 = beam;
  }
  if (!finite) {
    for (std::size_t j = 0; j < point_count; ++j) {
      if (!std::isfinite(point[j].x) || !std::isfinite(point[j].y))
        throw InvalidInput("points", "corrected point " + std::to_string(j) + " is not finite");
    }
  }
  if (point_count > 0) {
    // For a full-circle grid the last beam also neighbours the first.
    const std::size_t last = point_count - 1;
    const bool wraps = sweep.isFullCircle() && point_count > 2 && points.front().beam_index == 0 &&
                       points.back().beam_index + 1 == sweep.binCount();
    point[last].next = wraps ? 0 : kNoPoint;
    joined[last] = wraps && isJoined(last, 0);
    if (measureResidual(last, previous(last)))
      candidates[candidate_count++] = static_cast<std::uint32_t>(last);
    if (wraps && measureResidual(0, last)) {  // point 0 comes first
      std::copy_backward(candidates, candidates + candidate_count, candidates + candidate_count + 1);
      candidates[0] = 0;
      ++candidate_count;
    }
  }
  candidate_count_ = candidate_count;
}

double ReferenceRebinner::rangeOf(std::size_t j) {
  if (range_[j] == 0.0)  // not yet (a point at the sensor's origin computes its 0 again)
    range_[j] = std::sqrt(point_[j].x * point_[j].x + point_[j].y * point_[j].y);
  return range_[j];
}

double ReferenceRebinner::bearingOf(std::size_t j) {
  if (bearing_[j] == 0.0)  // not yet (or a bearing of 0, computed again)
    bearing_[j] = fastAtan2(point_[j].y, point_[j].x);
  return bearing_[j];
}

void ReferenceRebinner::findFlatPoints() {
  const std::size_t point_count = point_.size();
  // The scan's own noise: the median distance of points within one contour, from every stride-th.
  const std::size_t stride = std::max<std::size_t>(1, candidate_count_ / kNoiseSampleSize);
  noise_sample_.resize((candidate_count_ + stride - 1) / stride);
  for (std::size_t s = 0, k = 0; s < candidate_count_; s += stride, ++k)
    noise_sample_[k] = residual(candidates_[s]);
  double median = 0.0;
  if (!noise_sample_.empty()) {
    const auto middle = noise_sample_.begin() + static_cast<std::ptrdiff_t>(noise_sample_.size() / 2);
    std::nth_element(noise_sample_.begin(), middle, noise_sample_.end());
    median = *middle;
  }
  flat_tolerance_ = kFlatToleranceFloor + kFlatToleranceMedians * median;
  const double tolerance2 = flat_tolerance_ * flat_tolerance_;
  flat_.resize(point_count);
  char* const flat = flat_.data();
  const PointState* const point = point_.data();
  for (std::size_t j = 0; j < point_count; ++j) {
    const double length2 = point[j].length2;
    if (length2 == 0.0) {  // no neighbours' line: never flat
      flat[j] = 0;
      continue;
    }
    const double limit2 = tolerance2 * length2;
    const double cross2 = point[j].cross * point[j].cross;
    if (cross2 <= limit2 * (1.0 - kSquaredMargin) && limit2 > 1e-200) {
      flat[j] = 1;
    } else if (cross2 >= limit2 * (1.0 + kSquaredMargin) && limit2 > 1e-200) {
      flat[j] = 0;
    } else {
      flat[j] = residual(j) <= flat_tolerance_;  // near the tolerance: as sqrt and division decide it
    }
  }
}

double ReferenceRebinner::residual(std::size_t j) const {
  // As |cross(e, j - p)| / |e| with e = next - previous, both kept by readPoints (length2 = |e|^2).
  return std::abs(point_[j].cross) / std::sqrt(point_[j].length2);
}

void ReferenceRebinner::classifyLinks(const BinSweep& sweep) {
  const std::size_t point_count = point_.size();
  link_.resize(point_count);
  corner_x_.resize(point_count);
  corner_y_.resize(point_count);
  // First the links one of whose points is flat (surfaces) and the corners; the rest wait (kStep) for
  // traceContours(), which tells a depth step from the surfaces on both sides.
  const PointState* const point = point_.data();
  const char* const flat = flat_.data();
  const char* const joined = joined_.data();
  Link* const link = link_.data();
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t q = point[j].next;
    if (q == kNoPoint) {
      link[j] = Link::kNone;
      continue;
    }
    // One of them flat (the line through its neighbours holds the other), and joined or (a wall seen at
    // a grazing angle, its points farther apart than the gap) nearly joined.
    if ((flat[j] || flat[q]) && (joined[j] || nearlyJoined(j, q, sweep))) {
      link[j] = Link::kSurface;
      continue;
    }
    // A corner: its three links joined; or, in a scan with little noise, a wall at a grazing angle (its
    // points farther apart than the gap): nearly joined, and a wall's line nearly joined only where a
    // third point confirms it (`confirm` flat: on the line through its neighbours).
    const auto close = [&](std::size_t a, std::size_t b, std::size_t confirm) {
      return joined_[a] || (nearlyJoined(a, b, sweep) && (confirm == kNoPoint || flat_[confirm]));
    };
    const std::size_t p = previous(j), r = point_[q].next;
    if (p != kNoPoint && r != kNoPoint && close(j, q, kNoPoint) && close(p, j, p) && close(q, r, r) &&
        findCorner(p, j, q, r, corner_x_[j], corner_y_[j])) {
      link[j] = Link::kCorner;
      continue;
    }
    link[j] = Link::kStep;
  }
}

ReferenceRebinner::Link ReferenceRebinner::resolveStep(std::size_t j, const BinSweep& sweep) {
  // A waiting link is a depth step when its farther point continues a surface on its other side.
  const std::size_t q = point_[j].next;
  const bool far_is_next = rangeOf(q) > rangeOf(j);
  const std::size_t far_side = far_is_next ? q : previous(j);
  const bool far_continues = far_side != kNoPoint && link_[far_side] == Link::kSurface;
  if (!far_continues)
    return joined_[j] ? Link::kChord : Link::kNone;
  const bool adjacent =
      std::abs(wrapDelta(bearingOf(q) - bearingOf(j))) <= kMaxStepBins * sweep.absIncrement();
  if (!adjacent || std::abs(rangeOf(q) - rangeOf(j)) <= flat_tolerance_ ||
      !continuationIsSure(far_is_next ? j : q, far_is_next ? q : j,
                          far_is_next ? point_[q].next : previous(j))) {
    return joined_[j] ? Link::kChord : Link::kNone;
  }
  return Link::kStep;
}

void ReferenceRebinner::traceContours(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  const double abs_increment = sweep.absIncrement();
  const auto intensity = [&](std::size_t j) { return points[j].intensity; };
  // Precise enough that a guess, not the noise, would be the error: guesses are left out (kGuessBudget).
  const bool precise = flat_tolerance_ <= kStepErrorBudget;
  const auto continues = [](Link link) { return link != Link::kNone && link != Link::kStep; };
  // Plain pointers and locals: a store through a byte (a resolved link) may alias any member.
  const PointState* const point = point_.data();
  Link* const link = link_.data();
  const bool running = running_;
  const Bins bins = this->bins(points);
  bool left_continues = false;  // the link of j - 1 (resolved) continues a contour
  // One pass over the links in order (so the nearest crossing of a bin is chosen as before when two are
  // equally near); the points where a contour ends are noted on the way and traced after every link.
  ends_.clear();
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t q = point[j].next;
    Link kind = link[j];
    if (kind == Link::kStep) {
      kind = resolveStep(j, sweep);  // a step's far side is only compared with kSurface: order is free
      link[j] = kind;
    }
    if (kind == Link::kSurface ||
        (kind == Link::kChord &&
         !(precise && std::hypot(point[q].x - point[j].x, point[q].y - point[j].y) > 2.0 * kGuessBudget))) {
      // A segment (a chord longer than 2 kGuessBudget: its surface cannot be told, left empty). Less than
      // a quarter turn wide (so not through the sensor): by running bin positions.
      // (0 in a scan without intensities: read, never used)
      const double ax = point[j].x, ay = point[j].y, bx = point[q].x, by = point[q].y;
      if (running && ax * bx + ay * by > 0.0 && point[j].position != kUnknown &&
          point[q].position != kUnknown) {
        bins.crossRays(ax, ay, point[j].position, point[j].side_low, point[j].side_high, j, bx, by,
                       point[q].position, point[q].side_low, point[q].side_high, q);
      } else {
        crossSegmentByBearing(ax, ay, bearingOf(j), intensity(j), bx, by, bearingOf(q), intensity(q), sweep);
      }
    } else if (kind == Link::kCorner) {
      crossCorner(points, j, q, sweep);
    } else if (kind == Link::kStep) {
      // The far contour's end segment continued behind the near point, over the bearings between.
      const bool far_is_next = rangeOf(q) > rangeOf(j);
      const std::size_t near = far_is_next ? j : q, far = far_is_next ? q : j;
      const std::size_t beyond = far_is_next ? point[q].next : previous(j);
      const double delta = wrapDelta(bearingOf(far) - bearingOf(near));
      extendLine(points, far, point[far].x - point[beyond].x, point[far].y - point[beyond].y, kInfinity,
                 rangeOf(near), std::min(bearingOf(near), bearingOf(near) + delta), std::abs(delta), sweep,
                 kMaxStepSlant, false, rangeOf(far) + flat_tolerance_);
    }
    // Both links of point j are final now (point 0's left one, the full circle's last, comes last). A
    // link of j - 1 that continues a contour joins it to j.
    const bool right_continues = continues(kind);
    if (j > 0 && !(left_continues && right_continues))
      ends_.push_back(std::size_t{j});  // a copy: j's own address never taken, so it stays in a register
    left_continues = right_continues;
  }
  if (point_count > 0) {
    const std::size_t p = previous(0);
    const Link right = point[0].next == kNoPoint ? Link::kNone : link[0];
    if (!(continues(p == kNoPoint ? Link::kNone : link[p]) && continues(right)))
      ends_.insert(ends_.begin(), 0);
  }
  // Contour ends: where a point continues a contour on one side only, or on neither (a lone point).
  for (const std::size_t j : ends_) {
    const std::size_t p = previous(j);
    const Link left = p == kNoPoint ? Link::kNone : link_[p];
    const Link right = point_[j].next == kNoPoint ? Link::kNone : link_[j];
    const double half_bin = 0.5 * abs_increment;
    const auto endReach = [&](std::size_t a, std::size_t b) {
      return precise ? std::min(kGuessBudget, joinGap(a, b, abs_increment)) : joinGap(a, b, abs_increment);
    };
    if (!continues(left) && !continues(right)) {
      // Lone return: a facet facing the sensor.
      extendLine(points, j, -point_[j].y, point_[j].x, endReach(j, j), 0.0, bearingOf(j) - half_bin,
                 abs_increment, sweep);
      continue;
    }
    const bool from_left = continues(left);
    // Follow the end segment (from the neighbour, or the corner, towards j) for up to half a bin; the
    // near end of a step only into bins the far contour did not reach.
    const Link end = from_left ? right : left;
    const bool near_end_of_step = end == Link::kStep && rangeOf(j) < rangeOf(from_left ? point_[j].next : p);
    const std::size_t neighbour = from_left ? p : point_[j].next;
    const Link kept = from_left ? left : right;
    const std::size_t corner_of = from_left ? p : j;
    const double nx = kept == Link::kCorner ? corner_x_[corner_of] : point_[neighbour].x;
    const double ny = kept == Link::kCorner ? corner_y_[corner_of] : point_[neighbour].y;
    extendLine(points, j, point_[j].x - nx, point_[j].y - ny, endReach(j, neighbour), 0.0,
               bearingOf(j) - half_bin - kBearingError, abs_increment + 2.0 * kBearingError, sweep, 0.0,
               near_end_of_step);
  }
}

void ReferenceRebinner::writeNearestCrossings(float no_return, RebinnedScan& out) {
  const std::size_t bin_count = best_range_.size();
  out.ranges.resize(bin_count);
  // Each bin read, written out and left empty for the next scan: no separate clearing pass. A bin holds
  // +inf or a finite range (offers keep only ranges below what it has), so "finite" is "below +inf";
  // plain pointers, so nothing is loaded again after a store.
  double* const best_range = best_range_.data();
  float* const ranges = out.ranges.data();
  for (std::size_t b = 0; b < bin_count; ++b) {
    const double range = best_range[b];
    ranges[b] = range < kInfinity ? static_cast<float>(range) : no_return;
    best_range[b] = kInfinity;
  }
  if (with_intensities_) {
    out.intensities.resize(bin_count);
    for (std::size_t b = 0; b < bin_count; ++b) {
      out.intensities[b] = best_intensity_[b];
      best_intensity_[b] = 0.0f;
    }
  } else {
    out.intensities.clear();
  }
}

bool ReferenceRebinner::nearlyJoined(std::size_t a, std::size_t b, const BinSweep& sweep) {
  const double abs_increment = sweep.absIncrement();
  // the flat test is evidence of one surface only when the noise is small against the error budget
  if (flat_tolerance_ > kStepErrorBudget)
    return false;
  const double dx = point_[b].x - point_[a].x, dy = point_[b].y - point_[a].y;
  const double limit = kFlatJoinGaps * joinGap(a, b, abs_increment);
  return std::abs(wrapDelta(bearingOf(b) - bearingOf(a))) <= kMaxStepBins * abs_increment &&
         dx * dx + dy * dy <= limit * limit;
}

double ReferenceRebinner::joinGap(std::size_t a, std::size_t b, double abs_increment) {
  return config_.min_gap + config_.gap_factor * std::max(rangeOf(a), rangeOf(b)) * abs_increment;
}

bool ReferenceRebinner::continuationIsSure(std::size_t near, std::size_t far, std::size_t beyond) {
  if (beyond == kNoPoint)
    return false;
  const double segment = std::hypot(point_[far].x - point_[beyond].x, point_[far].y - point_[beyond].y);
  // [m] how far the continuation runs along a wall facing the sensor: to the near point's bearing
  const double run = rangeOf(far) * std::abs(wrapDelta(bearingOf(far) - bearingOf(near)));
  return segment > 0.0 && flat_tolerance_ * (1.0 + run / segment) <= kStepErrorBudget;
}

std::size_t ReferenceRebinner::previous(std::size_t j) const {
  const std::size_t candidate = j > 0 ? j - 1 : point_.size() - 1;
  return point_[candidate].next == j ? candidate : kNoPoint;
}

bool ReferenceRebinner::findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1,
                                   double& corner_x, double& corner_y) const {
  const double ax = point_[a].x, ay = point_[a].y, bx = point_[b].x, by = point_[b].y;
  const double dax = ax - point_[a0].x, day = ay - point_[a0].y;  // along the wall before a, towards a
  const double dbx = point_[b1].x - bx, dby = point_[b1].y - by;  // along the wall after b, away from b
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

void ReferenceRebinner::crossCorner(const Points& points, std::size_t j, std::size_t q,
                                    const BinSweep& sweep) {
  const float j_intensity = points[j].intensity, q_intensity = points[q].intensity;
  const double cx = corner_x_[j], cy = corner_y_[j];
  if (running_ && point_[j].x * cx + point_[j].y * cy > 0.0 && cx * point_[q].x + cy * point_[q].y > 0.0 &&
      point_[j].position != kUnknown && point_[q].position != kUnknown) {
    double low = 0.0, high = 0.0;
    const std::size_t corner = rays().locate(cx, cy, point_[j].position, low, high);
    if (corner != kUnknown) {
      const Bins bins = this->bins(points);
      bins.crossRays(point_[j].x, point_[j].y, point_[j].position, point_[j].side_low, point_[j].side_high, j,
                     cx, cy, corner, low, high, j);
      bins.crossRays(cx, cy, corner, low, high, q, point_[q].x, point_[q].y, point_[q].position,
                     point_[q].side_low, point_[q].side_high, q);
      return;
    }
  }
  const double corner_bearing = fastAtan2(cy, cx);
  crossSegmentByBearing(point_[j].x, point_[j].y, bearingOf(j), j_intensity, cx, cy, corner_bearing,
                        j_intensity, sweep);
  crossSegmentByBearing(cx, cy, corner_bearing, q_intensity, point_[q].x, point_[q].y, bearingOf(q),
                        q_intensity, sweep);
}

void ReferenceRebinner::crossSegmentByBearing(double ax, double ay, double a_bearing, float a_intensity,
                                              double bx, double by, double b_bearing, float b_intensity,
                                              const BinSweep& sweep) {
  const double delta = wrapDelta(b_bearing - a_bearing);
  if (std::abs(delta) >= M_PI - 1e-6)
    return;  // passes through the sensor: not a visible surface
  const double ex = bx - ax, ey = by - ay;
  sweep.forEachBinIn(std::min(a_bearing, a_bearing + delta) - kBearingError,
                     std::abs(delta) + 2.0 * kBearingError, [&](std::size_t bin) {
                       const double denominator = cross(ray_cos_[bin], ray_sin_[bin], ex, ey);
                       if (denominator == 0.0)
                         return;
                       const double u = cross(ax, ay, ray_cos_[bin], ray_sin_[bin]) / denominator;
                       if (u < -kVertexTolerance || u > 1.0 + kVertexTolerance)
                         return;
                       const double range = cross(ax, ay, ex, ey) / denominator;
                       if (range <= 0.0)
                         return;
                       offer(bin, range, static_cast<float>((1.0 - u) * a_intensity + u * b_intensity));
                     });
}

void ReferenceRebinner::extendLine(const Points& points, std::size_t p, double dx, double dy, double reach,
                                   double min_range, double low, double width, const BinSweep& sweep,
                                   double max_slant, bool only_empty, double max_range) {
  const double px = point_[p].x, py = point_[p].y;
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

void ReferenceRebinner::offer(std::size_t bin, double range, float intensity) {
  if (range < best_range_[bin]) {
    best_range_[bin] = range;
    if (with_intensities_)
      best_intensity_[bin] = intensity;
  }
}

}  // namespace lidar_deskew::test
