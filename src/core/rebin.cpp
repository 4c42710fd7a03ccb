#include "lidar_deskew/core/rebin.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lidar_deskew::core {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
/// Tolerance on the segment parameter of a crossing: a ray through a contour's vertex meets it.
constexpr double kVertexTolerance = 1e-9;

inline double cross(double ax, double ay, double bx, double by) {
  return ax * by - ay * bx;
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
  const ReturnTest is_return(scan);
  for (float range : scan.ranges) {
    if (!is_return(range))
      return range;
  }
  return std::numeric_limits<float>::infinity();
}

ScanRebinner::ScanRebinner(const RebinConfig& config) : config_(config) {
  config_.validate();
}

void ScanRebinner::updateRays(const AngleGrid& grid) {
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

void ScanRebinner::rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return,
                         RebinnedScan& out) {
  checkGrid(grid);
  updateRays(grid);
  clearBins(grid.count);
  computePolarPoints(corrected.points);
  const BinSweep sweep(grid);
  linkContourNeighbours(corrected.points, sweep);
  traceContours(corrected.points, sweep);
  writeNearestCrossings(corrected.has_intensities, no_return, out);
}

void ScanRebinner::clearBins(std::size_t bin_count) {
  best_range_.assign(bin_count, std::numeric_limits<double>::infinity());
  best_intensity_.assign(bin_count, 0.0f);
}

void ScanRebinner::computePolarPoints(const Points& points) {
  const std::size_t point_count = points.size();
  point_range_.resize(point_count);
  point_bearing_.resize(point_count);
  for (std::size_t j = 0; j < point_count; ++j) {
    const Eigen::Vector3d& p = points[j].position;
    if (!std::isfinite(p.x()) || !std::isfinite(p.y())) {
      throw InvalidInput("points", "corrected point " + std::to_string(j) + " is not finite");
    }
    point_range_[j] = std::sqrt(p.x() * p.x() + p.y() * p.y());
    point_bearing_[j] = std::atan2(p.y(), p.x());
  }
}

void ScanRebinner::linkContourNeighbours(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  linked_to_next_.assign(point_count, 0);
  for (std::size_t j = 0; j + 1 < point_count; ++j) {
    linked_to_next_[j] = points[j + 1].beam_index == points[j].beam_index + 1 &&
                         joined(points, j, j + 1, sweep.absIncrement());
  }
  // For a full-circle grid the last beam also neighbours the first.
  if (sweep.isFullCircle() && point_count > 2 && points.front().beam_index == 0 &&
      points.back().beam_index + 1 == sweep.binCount()) {
    linked_to_next_[point_count - 1] = joined(points, point_count - 1, 0, sweep.absIncrement());
  }
}

void ScanRebinner::traceContours(const Points& points, const BinSweep& sweep) {
  const std::size_t point_count = points.size();
  const double abs_increment = sweep.absIncrement();
  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t next = j + 1 < point_count ? j + 1 : 0;
    const std::size_t previous = j > 0 ? j - 1 : point_count - 1;
    const bool has_next = linked_to_next_[j];
    const bool has_previous = point_count > 1 && linked_to_next_[previous] && previous != j;
    if (has_next)
      crossSegment(points, j, next, sweep);
    if (has_next && has_previous)
      continue;
    const Eigen::Vector3d& p = points[j].position;
    if (!has_next && !has_previous) {
      // Lone return: a facet facing the sensor.
      extendEnd(points, j, -p.y(), p.x(), joinGap(j, j, abs_increment), sweep);
    } else {
      const std::size_t neighbour = has_next ? next : previous;
      const Eigen::Vector3d& q = points[neighbour].position;
      extendEnd(points, j, p.x() - q.x(), p.y() - q.y(), joinGap(j, neighbour, abs_increment), sweep);
    }
  }
}

void ScanRebinner::writeNearestCrossings(bool has_intensities, float no_return, RebinnedScan& out) const {
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

double ScanRebinner::joinGap(std::size_t a, std::size_t b, double abs_increment) const {
  return config_.min_gap + config_.gap_factor * std::max(point_range_[a], point_range_[b]) * abs_increment;
}

bool ScanRebinner::joined(const Points& points, std::size_t a, std::size_t b, double abs_increment) const {
  const double dx = points[b].position.x() - points[a].position.x();
  const double dy = points[b].position.y() - points[a].position.y();
  const double limit = joinGap(a, b, abs_increment);
  return dx * dx + dy * dy <= limit * limit;
}

void ScanRebinner::crossSegment(const Points& points, std::size_t a, std::size_t b, const BinSweep& sweep) {
  double delta = point_bearing_[b] - point_bearing_[a];  // bearings in [-pi, pi]: wrap once
  if (delta > M_PI)
    delta -= kTwoPi;
  if (delta < -M_PI)
    delta += kTwoPi;
  if (std::abs(delta) >= M_PI - 1e-9)
    return;  // passes through the sensor: not a visible surface
  const double ax = points[a].position.x(), ay = points[a].position.y();
  const double ex = points[b].position.x() - ax, ey = points[b].position.y() - ay;
  sweep.forEachBinIn(
      std::min(point_bearing_[a], point_bearing_[a] + delta), std::abs(delta), [&](std::size_t bin) {
        const double denominator = cross(ray_cos_[bin], ray_sin_[bin], ex, ey);
        if (denominator == 0.0)
          return;
        const double u = cross(ax, ay, ray_cos_[bin], ray_sin_[bin]) / denominator;
        if (u < -kVertexTolerance || u > 1.0 + kVertexTolerance)
          return;
        const double range = cross(ax, ay, ex, ey) / denominator;
        if (range <= 0.0)
          return;
        offer(bin, range, static_cast<float>((1.0 - u) * points[a].intensity + u * points[b].intensity));
      });
}

void ScanRebinner::extendEnd(const Points& points, std::size_t p, double dx, double dy, double reach,
                             const BinSweep& sweep) {
  const double px = points[p].position.x(), py = points[p].position.y();
  const double direction_norm = std::sqrt(dx * dx + dy * dy);
  if (direction_norm == 0.0)
    return;
  const double abs_increment = sweep.absIncrement();
  sweep.forEachBinIn(point_bearing_[p] - 0.5 * abs_increment, abs_increment, [&](std::size_t bin) {
    const double denominator = cross(ray_cos_[bin], ray_sin_[bin], dx, dy);
    if (denominator == 0.0)
      return;
    const double u = cross(px, py, ray_cos_[bin], ray_sin_[bin]) / denominator;
    if (std::abs(u) * direction_norm > reach)
      return;
    const double range = cross(px, py, dx, dy) / denominator;
    if (range > 0.0)
      offer(bin, range, points[p].intensity);
  });
}

void ScanRebinner::offer(std::size_t bin, double range, float intensity) {
  if (range < best_range_[bin]) {
    best_range_[bin] = range;
    best_intensity_[bin] = intensity;
  }
}

}  // namespace lidar_deskew::core
