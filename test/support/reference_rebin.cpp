// Test support: the re-binner as it was before the one-pass rewrite (issue 25), frozen (see
// reference_rebin.h). A copy of src/core/rebin.cpp at that commit;
// fastAtan2 is the core's own (src/core/fast_atan2.h, which issue 25 did not change).
#include "support/reference_rebin.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "../../src/core/fast_atan2.h"

namespace lidar_deskew::test {
using core::AngleGrid;
using core::DeskewedScan;
using core::InvalidInput;
using core::RebinConfig;
using core::RebinnedScan;

namespace {

using core::detail::fastAtan2;
using core::detail::kFastAtan2Error;

constexpr double kTwoPi = 2.0 * M_PI;
/// Tolerance on the segment parameter of a crossing: a ray through a contour's vertex meets it.
constexpr double kVertexTolerance = 1e-9;

inline double cross(double ax, double ay, double bx, double by) {
  return ax * by - ay * bx;
}

/// [rad] bearings are off by at most this: intervals of bins are widened by it (the crossing test is exact).
constexpr double kBearingError = 2.0 * kFastAtan2Error;

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

void ReferenceRebinner::updateRays(const AngleGrid& grid) {
  if (ray_cos_.size() == grid.count && rays_grid_.angle_min == grid.angle_min &&
      rays_grid_.angle_increment == grid.angle_increment) {
    return;
  }
  rays_grid_ = grid;
  ray_cos_.resize(grid.count);
  ray_sin_.resize(grid.count);
  for (std::size_t b = 0; b < grid.count; ++b) {
    const double angle = static_cast<double>(grid.angle_min) + static_cast<double>(b) * grid.angle_increment;
    ray_cos_[b] = std::cos(angle);
    ray_sin_[b] = std::sin(angle);
  }
}

void ReferenceRebinner::rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return,
                              RebinnedScan& out) {
  checkGrid(grid);
  updateRays(grid);
  clearBins(grid.count);
  computePolarPoints(corrected.points);
  const BinSweep sweep(grid);
  linkContourNeighbours(corrected.points, sweep);
  findFlatPoints();
  classifyLinks(sweep);
  traceContours(corrected.points, sweep);
  writeNearestCrossings(corrected.has_intensities, no_return, out);
}

void ReferenceRebinner::clearBins(std::size_t bin_count) {
  best_range_.assign(bin_count, std::numeric_limits<double>::infinity());
  best_intensity_.assign(bin_count, 0.0f);
}

void ReferenceRebinner::computePolarPoints(const Points& points) {
  const std::size_t point_count = points.size();
  x_.resize(point_count);
  y_.resize(point_count);
  range_.resize(point_count);
  bearing_.resize(point_count);
  for (std::size_t j = 0; j < point_count; ++j) {
    const double x = points[j].position.x(), y = points[j].position.y();
    if (!std::isfinite(x) || !std::isfinite(y)) {
      throw InvalidInput("points", "corrected point " + std::to_string(j) + " is not finite");
    }
    x_[j] = x;
    y_[j] = y;
    range_[j] = std::sqrt(x * x + y * y);
    bearing_[j] = fastAtan2(y, x);
  }
}

void ReferenceRebinner::linkContourNeighbours(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  next_.assign(point_count, kNoPoint);
  joined_.assign(point_count, 0);
  for (std::size_t j = 0; j + 1 < point_count; ++j) {
    if (points[j + 1].beam_index == points[j].beam_index + 1)
      next_[j] = j + 1;
  }
  // For a full-circle grid the last beam also neighbours the first.
  if (sweep.isFullCircle() && point_count > 2 && points.front().beam_index == 0 &&
      points.back().beam_index + 1 == sweep.binCount()) {
    next_[point_count - 1] = 0;
  }
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t k = next_[j];
    if (k == kNoPoint)
      continue;
    const double dx = x_[k] - x_[j], dy = y_[k] - y_[j];
    const double limit = joinGap(j, k, sweep.absIncrement());
    joined_[j] = dx * dx + dy * dy <= limit * limit;
  }
}

void ReferenceRebinner::findFlatPoints() {
  const std::size_t point_count = x_.size();
  residuals_.assign(point_count, -1.0);
  std::size_t candidates = 0;
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t p = previous(j), q = next_[j];
    if (p == kNoPoint || q == kNoPoint)
      continue;
    const double ex = x_[q] - x_[p], ey = y_[q] - y_[p];
    const double length = std::sqrt(ex * ex + ey * ey);
    if (length == 0.0)
      continue;
    residuals_[j] = std::abs(cross(ex, ey, x_[j] - x_[p], y_[j] - y_[p])) / length;
    candidates += joined_[p] && joined_[j];
  }
  // The scan's own noise: the median distance of points within one contour, from every stride-th.
  noise_sample_.clear();
  const std::size_t stride = std::max<std::size_t>(1, candidates / kNoiseSampleSize);
  std::size_t seen = 0;
  for (std::size_t j = 0; j < point_count; ++j) {
    if (residuals_[j] >= 0.0 && joined_[j] && joined_[previous(j)] && seen++ % stride == 0)
      noise_sample_.push_back(residuals_[j]);
  }
  double median = 0.0;
  if (!noise_sample_.empty()) {
    const auto middle = noise_sample_.begin() + static_cast<std::ptrdiff_t>(noise_sample_.size() / 2);
    std::nth_element(noise_sample_.begin(), middle, noise_sample_.end());
    median = *middle;
  }
  flat_tolerance_ = kFlatToleranceFloor + kFlatToleranceMedians * median;
  flat_.resize(point_count);
  for (std::size_t j = 0; j < point_count; ++j)
    flat_[j] = residuals_[j] >= 0.0 && residuals_[j] <= flat_tolerance_;
}

void ReferenceRebinner::classifyLinks(const BinSweep& sweep) {
  const std::size_t point_count = x_.size();
  link_.assign(point_count, Link::kNone);
  corner_x_.resize(point_count);
  corner_y_.resize(point_count);
  // First the links one of whose points is flat (surfaces) and the corners; the rest wait (kStep).
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t q = next_[j];
    if (q == kNoPoint)
      continue;
    // One of them flat (the line through its neighbours holds the other), and joined or (a wall seen at
    // a grazing angle, its points farther apart than the gap) nearly joined.
    if ((flat_[j] || flat_[q]) && (joined_[j] || nearlyJoined(j, q, sweep))) {
      link_[j] = Link::kSurface;
      continue;
    }
    // A corner: its three links joined; or, in a scan with little noise, a wall at a grazing angle (its
    // points farther apart than the gap): nearly joined, and a wall's line nearly joined only where a
    // third point confirms it (`confirm` flat: on the line through its neighbours).
    const auto close = [&](std::size_t a, std::size_t b, std::size_t confirm) {
      return joined_[a] || (nearlyJoined(a, b, sweep) && (confirm == kNoPoint || flat_[confirm]));
    };
    const std::size_t p = previous(j), r = next_[q];
    if (p != kNoPoint && r != kNoPoint && close(j, q, kNoPoint) && close(p, j, p) && close(q, r, r) &&
        findCorner(p, j, q, r, corner_x_[j], corner_y_[j])) {
      link_[j] = Link::kCorner;
      continue;
    }
    link_[j] = Link::kStep;
  }
  // A waiting link is a depth step when its farther point continues a surface on its other side.
  for (std::size_t j = 0; j < point_count; ++j) {
    if (link_[j] != Link::kStep)
      continue;
    const std::size_t q = next_[j];
    const bool far_is_next = range_[q] > range_[j];
    const std::size_t far_side = far_is_next ? q : previous(j);
    const bool far_continues = far_side != kNoPoint && link_[far_side] == Link::kSurface;
    const bool adjacent =
        std::abs(wrapDelta(bearing_[q] - bearing_[j])) <= kMaxStepBins * sweep.absIncrement();
    if (!far_continues || !adjacent || std::abs(range_[q] - range_[j]) <= flat_tolerance_ ||
        !continuationIsSure(far_is_next ? j : q, far_is_next ? q : j, far_is_next ? next_[q] : previous(j))) {
      link_[j] = joined_[j] ? Link::kChord : Link::kNone;
    }
  }
}

void ReferenceRebinner::traceContours(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  const double abs_increment = sweep.absIncrement();
  const auto intensity = [&](std::size_t j) { return points[j].intensity; };
  // Precise enough that a guess, not the noise, would be the error: guesses are left out (kGuessBudget).
  const bool precise = flat_tolerance_ <= kStepErrorBudget;
  const auto endReach = [&](std::size_t a, std::size_t b) {
    return precise ? std::min(kGuessBudget, joinGap(a, b, abs_increment)) : joinGap(a, b, abs_increment);
  };
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t q = next_[j];
    switch (link_[j]) {
      case Link::kNone:
        break;
      case Link::kChord:
        if (precise && std::hypot(x_[q] - x_[j], y_[q] - y_[j]) > 2.0 * kGuessBudget)
          break;  // its surface cannot be told: left empty
        [[fallthrough]];
      case Link::kSurface:
        crossSegment(x_[j], y_[j], bearing_[j], intensity(j), x_[q], y_[q], bearing_[q], intensity(q), sweep);
        break;
      case Link::kCorner: {
        const double cx = corner_x_[j], cy = corner_y_[j], corner_bearing = fastAtan2(cy, cx);
        crossSegment(x_[j], y_[j], bearing_[j], intensity(j), cx, cy, corner_bearing, intensity(j), sweep);
        crossSegment(cx, cy, corner_bearing, intensity(q), x_[q], y_[q], bearing_[q], intensity(q), sweep);
        break;
      }
      case Link::kStep: {
        // The far contour's end segment continued behind the near point, over the bearings between.
        const bool far_is_next = range_[q] > range_[j];
        const std::size_t near = far_is_next ? j : q, far = far_is_next ? q : j;
        const std::size_t beyond = far_is_next ? next_[q] : previous(j);
        const double delta = wrapDelta(bearing_[far] - bearing_[near]);
        extendLine(points, far, x_[far] - x_[beyond], y_[far] - y_[beyond], kInfinity, range_[near],
                   std::min(bearing_[near], bearing_[near] + delta), std::abs(delta), sweep, kMaxStepSlant,
                   false, range_[far] + flat_tolerance_);
        break;
      }
    }
  }
  // Contour ends: where a point continues a contour on one side only, or on neither (a lone point).
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t p = previous(j);
    const Link left = p == kNoPoint ? Link::kNone : link_[p];
    const Link right = next_[j] == kNoPoint ? Link::kNone : link_[j];
    const auto continues = [](Link link) { return link != Link::kNone && link != Link::kStep; };
    const double half_bin = 0.5 * abs_increment;
    if (continues(left) && continues(right))
      continue;
    if (!continues(left) && !continues(right)) {
      // Lone return: a facet facing the sensor.
      extendLine(points, j, -y_[j], x_[j], endReach(j, j), 0.0, bearing_[j] - half_bin, abs_increment, sweep);
      continue;
    }
    const bool from_left = continues(left);
    // Follow the end segment (from the neighbour, or the corner, towards j) for up to half a bin; the
    // near end of a step only into bins the far contour did not reach.
    const Link end = from_left ? right : left;
    const bool near_end_of_step = end == Link::kStep && range_[j] < range_[from_left ? next_[j] : p];
    const std::size_t neighbour = from_left ? p : next_[j];
    const Link link = from_left ? left : right;
    const std::size_t corner_of = from_left ? p : j;
    const double nx = link == Link::kCorner ? corner_x_[corner_of] : x_[neighbour];
    const double ny = link == Link::kCorner ? corner_y_[corner_of] : y_[neighbour];
    extendLine(points, j, x_[j] - nx, y_[j] - ny, endReach(j, neighbour), 0.0,
               bearing_[j] - half_bin - kBearingError, abs_increment + 2.0 * kBearingError, sweep, 0.0,
               near_end_of_step);
  }
}

void ReferenceRebinner::writeNearestCrossings(bool has_intensities, float no_return,
                                              RebinnedScan& out) const {
  const std::size_t bin_count = best_range_.size();
  out.ranges.resize(bin_count);
  for (std::size_t b = 0; b < bin_count; ++b) {
    out.ranges[b] = std::isfinite(best_range_[b]) ? static_cast<float>(best_range_[b]) : no_return;
  }
  if (has_intensities) {
    out.intensities = best_intensity_;
  } else {
    out.intensities.clear();
  }
}

bool ReferenceRebinner::nearlyJoined(std::size_t a, std::size_t b, const BinSweep& sweep) const {
  const double abs_increment = sweep.absIncrement();
  const double dx = x_[b] - x_[a], dy = y_[b] - y_[a];
  const double limit = kFlatJoinGaps * joinGap(a, b, abs_increment);
  // the flat test is evidence of one surface only when the noise is small against the error budget
  return flat_tolerance_ <= kStepErrorBudget &&
         std::abs(wrapDelta(bearing_[b] - bearing_[a])) <= kMaxStepBins * abs_increment &&
         dx * dx + dy * dy <= limit * limit;
}

double ReferenceRebinner::joinGap(std::size_t a, std::size_t b, double abs_increment) const {
  return config_.min_gap + config_.gap_factor * std::max(range_[a], range_[b]) * abs_increment;
}

bool ReferenceRebinner::continuationIsSure(std::size_t near, std::size_t far, std::size_t beyond) const {
  if (beyond == kNoPoint)
    return false;
  const double segment = std::hypot(x_[far] - x_[beyond], y_[far] - y_[beyond]);
  // [m] how far the continuation runs along a wall facing the sensor: to the near point's bearing
  const double run = range_[far] * std::abs(wrapDelta(bearing_[far] - bearing_[near]));
  return segment > 0.0 && flat_tolerance_ * (1.0 + run / segment) <= kStepErrorBudget;
}

std::size_t ReferenceRebinner::previous(std::size_t j) const {
  const std::size_t candidate = j > 0 ? j - 1 : next_.size() - 1;
  return next_[candidate] == j ? candidate : kNoPoint;
}

bool ReferenceRebinner::findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1,
                                   double& corner_x, double& corner_y) const {
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

void ReferenceRebinner::crossSegment(double ax, double ay, double a_bearing, float a_intensity, double bx,
                                     double by, double b_bearing, float b_intensity, const BinSweep& sweep) {
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

void ReferenceRebinner::offer(std::size_t bin, double range, float intensity) {
  if (range < best_range_[bin]) {
    best_range_[bin] = range;
    best_intensity_[bin] = intensity;
  }
}

}  // namespace lidar_deskew::test
