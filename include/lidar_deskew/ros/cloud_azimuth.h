// Per-point times of a spinning LIDAR's cloud that carries none, from each point's azimuth: the
// opt-in fallback for clouds without a time field (docs/CLOUDS.md, "No time field: azimuth timing").
// Message-free: it takes the points in firing order and gives offsets from header.stamp.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

namespace lidar_deskew::ros_adapter {

/// How to time a cloud from its points' azimuth (parameters azimuth_timing, azimuth_direction,
/// azimuth_period, azimuth_stamp_at). Off unless asked for: a cloud without times is an error otherwise.
struct AzimuthTiming {
  bool enabled = false;  ///< azimuth_timing: time clouds without a time field from the azimuth
  /// azimuth_direction: cw | ccw, the head's spin seen from above (from +z of the cloud's frame).
  /// Velodyne and Ouster spin clockwise (their azimuth, or encoder count, grows clockwise from above).
  std::string direction = "cw";
  double period = 0.1;             ///< azimuth_period [s]: one revolution (10 Hz: 0.1)
  std::string stamp_at = "start";  ///< azimuth_stamp_at: start | end, header.stamp is the first or last point

  /// Throws core::InvalidInput naming the parameter (azimuth_direction, azimuth_period [s] in (0, 60],
  /// azimuth_stamp_at) for a bad value.
  void validate() const;
};

/// Closer to the spin axis than this [m] (horizontally), a point's azimuth is taken as undefined.
constexpr double kAzimuthMinRadius = 0.01;
/// A point at most this far [rad] behind the sweep's furthest azimuth so far is a beam fired later at
/// a lagging azimuth (per-beam azimuth offsets of a few degrees, the parallax of near points), not a
/// full revolution later; anything else is ahead of it.
constexpr double kAzimuthStagger = 1.5707963267948966;  // 90 deg
/// A sweep covers at most this many revolutions; more means the points are not in firing order.
constexpr double kAzimuthMaxRevolutions = 1.25;

/// Per-point time offsets [s] from header.stamp, from each point's azimuth in the cloud's (the
/// sensor's) frame. `points` [m] in firing order: an organized cloud column by column, with
/// `points_per_column` its height (a column's points were fired together); a dense cloud in its own
/// order, 1. The azimuth is the head's angle against the housing, whatever the robot does, so a point's
/// time is the angle the head has turned since the first point, over 2 pi, times `period`.
///
/// The rule: walking the points in firing order, the sweep angle is a running maximum. Each point's
/// azimuth is compared with the furthest sweep angle reached so far (in the spin direction): up to
/// kAzimuthStagger behind it, the point lags (a beam's azimuth offset, parallax) and takes the time of
/// that furthest angle, since firing order is time order; otherwise it is ahead by its angle difference
/// in [0, 2 pi - kAzimuthStagger), across a gap without returns if need be, and moves the sweep on.
/// The points of one column then all take their column's furthest angle. So offsets never decrease
/// along the firing order, a point just behind the start never becomes a period late, and a sweep of a
/// little more than a revolution goes on past `period` instead of wrapping to 0. A point without an
/// azimuth (non-finite: a no-return marker; or within kAzimuthMinRadius of the z axis, the origin
/// included) takes the offset of the point before it (of the first point with one, when first).
/// With stamp_at start the first point is at 0 and the offsets are >= 0; with end they are shifted so
/// that the last (the furthest) is 0, all <= 0.
///
/// Accuracy: exact (to float32 coordinates) where every beam of a column shares its azimuth (VLP-16).
/// Beams with azimuth offsets (OS1-64: about +-3.2 deg; VLP-32C: +-4.2 deg) put every point at its
/// column's leading beam; organized clouds with `points_per_column` lose nothing by it, but in a dense
/// cloud whose first point is not a leading beam every time is late by up to the offsets' spread over
/// 2 pi times `period` (6.4 deg at 10 Hz: 1.8 ms). Measured: docs/CLOUDS.md.
///
/// `offsets` gets one entry per point (empty for no points; all 0 when no point has an azimuth).
/// Throws core::InvalidInput: for bad parameters (validate()) or points_per_column 0;
/// "azimuth_direction" when the points turn the other way by more than 45 deg net; "azimuth_timing" when
/// they are not in firing order (from first to last they turn, or their azimuth sweeps, more than
/// kAzimuthMaxRevolutions: a filter reordered them?).
void azimuthOffsets(const std::vector<Eigen::Vector3d>& points, const AzimuthTiming& timing,
                    std::vector<double>& offsets, std::size_t points_per_column = 1);

}  // namespace lidar_deskew::ros_adapter
