#include "lidar_deskew/ros/cloud_azimuth.h"

#include <algorithm>
#include <cmath>

#include "lidar_deskew/core/types.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr double kDegrees = 180.0 / M_PI;
/// The points may turn against the spin by this much [rad] net (a column's beam offsets, parallax).
constexpr double kMostTurnedBack = M_PI / 4.0;

/// `angle` [rad] wrapped into [low, low + 2 pi).
double wrapFrom(double angle, double low) {
  return angle - kTwoPi * std::floor((angle - low) / kTwoPi);
}

}  // namespace

void AzimuthTiming::validate() const {
  if (direction != "cw" && direction != "ccw")
    throw core::InvalidInput("azimuth_direction", "must be one of cw|ccw, got '" + direction + "'");
  if (!(period > 0.0 && period <= 60.0))
    throw core::InvalidInput("azimuth_period", "must be in (0, 60] s, got " + formatNumber(period));
  if (stamp_at != "start" && stamp_at != "end")
    throw core::InvalidInput("azimuth_stamp_at", "must be one of start|end, got '" + stamp_at + "'");
}

void azimuthOffsets(const std::vector<Eigen::Vector3d>& points, const AzimuthTiming& timing,
                    std::vector<double>& offsets, std::size_t points_per_column) {
  timing.validate();
  if (points_per_column == 0)
    throw core::InvalidInput("points_per_column", "must be at least 1");
  const double spin = timing.direction == "ccw" ? 1.0 : -1.0;  // angles counted in the spin direction
  offsets.resize(points.size());
  bool started = false;
  double start = 0.0;     // [rad] spin angle of the first point with an azimuth
  double reached = 0.0;   // [rad] furthest sweep angle so far, from `start` (the running maximum)
  double previous = 0.0;  // [rad] spin angle of the last point with an azimuth
  double turned = 0.0;    // [rad] net turn from point to point (each step the nearer way round)
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& point = points[i];
    if (point.allFinite() && point.head<2>().squaredNorm() >= kAzimuthMinRadius * kAzimuthMinRadius) {
      const double angle = spin * std::atan2(point.y(), point.x());
      if (!started) {
        started = true;
        start = previous = angle;
      }
      turned += wrapFrom(angle - previous, -M_PI);
      previous = angle;
      // Ahead of the furthest angle by [-stagger, 2 pi - stagger): behind it is a lagging beam.
      const double ahead = wrapFrom(angle - start - reached, -kAzimuthStagger);
      if (ahead > 0.0)
        reached += ahead;
    }
    offsets[i] = reached;  // an angle [rad] for now
  }
  const double most = kTwoPi * kAzimuthMaxRevolutions;
  if (std::abs(turned) > most) {
    throw core::InvalidInput("azimuth_timing", "the points turn " + formatNumber(turned / kTwoPi) +
                                                   " revolutions from first to last, not one: are they "
                                                   "in firing order?");
  }
  if (turned < -kMostTurnedBack) {
    throw core::InvalidInput("azimuth_direction",
                             "is " + timing.direction + ", but the points turn " +
                                 (timing.direction == "cw" ? "counter-clockwise" : "clockwise") + " by " +
                                 formatNumber(-turned * kDegrees) + " deg");
  }
  if (reached > most) {
    throw core::InvalidInput("azimuth_timing", "the points' azimuth sweeps " +
                                                   formatNumber(reached / kTwoPi) +
                                                   " revolutions, not one: are they in firing order?");
  }
  // A column's points were fired together: each takes the furthest angle of its column (the last
  // entry: the angles never decrease), so the first column's lagging beams do not shift the start.
  for (std::size_t begin = 0; begin < offsets.size(); begin += points_per_column) {
    const std::size_t end = std::min(begin + points_per_column, offsets.size());
    std::fill(offsets.begin() + begin, offsets.begin() + end, offsets[end - 1]);
  }
  if (offsets.empty())
    return;
  const double zero = timing.stamp_at == "end" ? offsets.back() : offsets.front();
  for (double& offset : offsets)
    offset = (offset - zero) / kTwoPi * timing.period;
}

}  // namespace lidar_deskew::ros_adapter
