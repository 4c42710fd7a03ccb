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

}  // namespace

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
  updateRays(grid);
  best_range_.assign(bin_count, std::numeric_limits<double>::infinity());
  best_intensity_.assign(bin_count, 0.0f);

  const std::vector<DeskewedPoint>& points = corrected.points;
  const std::size_t point_count = points.size();
  const double abs_increment = std::abs(increment);
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

  // Bins whose ray angle lies in [low, low + width] (mod 2pi), width <= pi: visit(bin).
  const double inverse_increment = abs_increment > 0.0 ? 1.0 / abs_increment : 0.0;
  const bool wider_than_a_turn = abs_increment * static_cast<double>(bin_count - 1) >= kTwoPi - 1e-9;
  const auto visitBinsFrom = [&](double start, double width, auto&& visit) {
    // start, start + width: angles [rad] from angle_min along the grid's direction
    const double first = std::max(std::ceil(start * inverse_increment - 1e-6), 0.0);
    const double last =
        std::min(std::floor((start + width) * inverse_increment + 1e-6), static_cast<double>(bin_count - 1));
    for (double b = first; b <= last; b += 1.0)
      visit(static_cast<std::size_t>(b));
  };
  const auto forEachBinIn = [&](double low, double width, auto&& visit) {
    if (bin_count == 0)
      return;
    if (bin_count == 1) {
      const double offset = wrapToTurn(static_cast<double>(grid.angle_min) - low);
      if (offset <= width + 1e-12 || offset >= kTwoPi - 1e-12)
        visit(std::size_t{0});
      return;
    }
    const double start = wrapToTurn(increment > 0.0 ? low - grid.angle_min : grid.angle_min - (low + width));
    visitBinsFrom(start, width, visit);
    if (start + width >= kTwoPi - 1e-9)
      visitBinsFrom(start - kTwoPi, width, visit);  // past the grid's wrap
    if (wider_than_a_turn)
      visitBinsFrom(start + kTwoPi, width, visit);  // e.g. 361 x 1 deg
  };

  const auto offer = [&](std::size_t bin, double range, float intensity) {
    if (range < best_range_[bin]) {
      best_range_[bin] = range;
      best_intensity_[bin] = intensity;
    }
  };

  const auto gapLimit = [&](std::size_t a, std::size_t b) {
    return config_.min_gap + config_.gap_factor * std::max(point_range_[a], point_range_[b]) * abs_increment;
  };
  const auto joined = [&](std::size_t a, std::size_t b) {
    const double dx = points[b].position.x() - points[a].position.x();
    const double dy = points[b].position.y() - points[a].position.y();
    const double limit = gapLimit(a, b);
    return dx * dx + dy * dy <= limit * limit;
  };

  // Contour segment a -> b: every bin whose ray crosses it.
  const auto crossSegment = [&](std::size_t a, std::size_t b) {
    double delta = point_bearing_[b] - point_bearing_[a];  // bearings in [-pi, pi]: wrap once
    if (delta > M_PI)
      delta -= kTwoPi;
    if (delta < -M_PI)
      delta += kTwoPi;
    if (std::abs(delta) >= M_PI - 1e-9)
      return;  // passes through the sensor: not a visible surface
    const double ax = points[a].position.x(), ay = points[a].position.y();
    const double ex = points[b].position.x() - ax, ey = points[b].position.y() - ay;
    forEachBinIn(
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
  };

  // A contour end (or lone point) p: the line through p along `direction`, for bins within half a
  // bin of p's bearing, no farther from p than the join gap.
  const auto extendEnd = [&](std::size_t p, double dx, double dy, double reach) {
    const double px = points[p].position.x(), py = points[p].position.y();
    const double direction_norm = std::sqrt(dx * dx + dy * dy);
    if (direction_norm == 0.0)
      return;
    forEachBinIn(point_bearing_[p] - 0.5 * abs_increment, abs_increment, [&](std::size_t bin) {
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
  };

  // Links between consecutive points; for a full-circle grid the last beam also neighbours the first.
  std::vector<char>& linked_to_next = linked_to_next_;
  linked_to_next.assign(point_count, 0);
  for (std::size_t j = 0; j + 1 < point_count; ++j) {
    linked_to_next[j] = points[j + 1].beam_index == points[j].beam_index + 1 && joined(j, j + 1);
  }
  const bool full_circle = abs_increment * static_cast<double>(bin_count) >= kTwoPi - 0.5 * abs_increment;
  if (full_circle && point_count > 2 && points.front().beam_index == 0 &&
      points.back().beam_index + 1 == bin_count) {
    linked_to_next[point_count - 1] = joined(point_count - 1, 0);
  }

  for (std::size_t j = 0; j < point_count; ++j) {
    const std::size_t next = j + 1 < point_count ? j + 1 : 0;
    const std::size_t previous = j > 0 ? j - 1 : point_count - 1;
    const bool has_next = linked_to_next[j];
    const bool has_previous = point_count > 1 && linked_to_next[previous] && previous != j;
    if (has_next)
      crossSegment(j, next);
    if (has_next && has_previous)
      continue;
    const Eigen::Vector3d& p = points[j].position;
    if (!has_next && !has_previous) {
      // Lone return: a facet facing the sensor.
      extendEnd(j, -p.y(), p.x(), config_.min_gap + config_.gap_factor * point_range_[j] * abs_increment);
    } else {
      const std::size_t neighbour = has_next ? next : previous;
      const Eigen::Vector3d& q = points[neighbour].position;
      extendEnd(j, p.x() - q.x(), p.y() - q.y(), gapLimit(j, neighbour));
    }
  }

  out.ranges.resize(bin_count);
  for (std::size_t b = 0; b < bin_count; ++b) {
    out.ranges[b] = std::isfinite(best_range_[b]) ? static_cast<float>(best_range_[b]) : no_return;
  }
  if (corrected.has_intensities) {
    out.intensities = best_intensity_;
  } else {
    out.intensities.clear();
  }
}

}  // namespace lidar_deskew::core
