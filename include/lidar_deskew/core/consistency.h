// How well scans of one sensor agree where they overlap, in the fixed frame: a measure of a
// correction, or of a timing, that needs no ground truth (docs/CALIBRATION.md). ROS-free.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/core/types.h"

namespace lidar_deskew::core {

/// One scan's returns placed in the fixed frame (the plane of the laser), in beam order, with what
/// the measure needs to look points up along the scan's own rays.
class PlacedScan {
 public:
  PlacedScan() = default;
  /// `points` [m] in the fixed frame in beam order; `origin` [m] the laser's position there at `time`;
  /// `bearing_step` [rad] the beams' angular spacing (> 0).
  PlacedScan(TimeNs time, const Eigen::Vector2d& origin, double bearing_step,
             std::vector<Eigen::Vector2d> points);

  /// As the constructor, in this scan's own storage (no allocation once it has held as many points and
  /// bins): the points are what `fill` appends to the emptied vector it is given. A search that places
  /// every scan at each of hundreds of timings reuses its scans so. `indexed` false: the points alone,
  /// for a scan whose points are measured against others but never looked up in (distanceToContour()
  /// and contourHit() throw std::logic_error), without the index's cost.
  template <typename Fill>
  void assign(TimeNs time, const Eigen::Vector2d& origin, double bearing_step, Fill fill,
              bool indexed = true) {
    checkBearingStep(bearing_step);
    points_.clear();
    fill(points_);
    if (indexed) {
      index(time, origin, bearing_step);
    } else {
      time_ = time;
      origin_ = origin;
    }
    indexed_ = indexed;
  }
  /// Empties the scan (as a default-constructed one), keeping its storage for assign().
  void clear() { points_.clear(); }

  TimeNs time() const { return time_; }
  const Eigen::Vector2d& origin() const { return origin_; }
  const std::vector<Eigen::Vector2d>& points() const { return points_; }
  bool empty() const { return points_.empty(); }

  /// The distance [m] from `query` to this scan's contour near the ray from origin() through it:
  /// among the points whose bearing lies within two bearing steps of the query's, the nearest, and
  /// from it to the line through its contour neighbours (consecutive points closer than the join
  /// distance: 0.05 m + 5 x range x bearing step), or to the point itself when it has none. Sets
  /// `nearest` to the distance to that point. Returns false (no such point) when none lies within
  /// `radius` [m].
  bool distanceToContour(const Eigen::Vector2d& query, double radius, double& distance,
                         double& nearest) const;

  /// What distanceToContour() finds, with the place on the contour: the scan matcher's correspondence.
  struct ContourHit {
    double distance = 0.0;                            ///< [m] as distanceToContour()
    double nearest = 0.0;                             ///< [m] to the nearest point
    Eigen::Vector2d point = Eigen::Vector2d::Zero();  ///< [m] the nearest point of this scan
    /// unit normal of the contour's line through `point` (zero when it has no contour neighbours:
    /// `distance` is then to the point itself)
    Eigen::Vector2d normal = Eigen::Vector2d::Zero();
  };
  /// distanceToContour() with the nearest point and the contour's normal there.
  bool contourHit(const Eigen::Vector2d& query, double radius, ContourHit& hit) const;
  /// distanceToContour() of every `stride`-th of `queries` (from the first): adds min(distance, cap) of
  /// each found to `sum`, in order, and returns how many were found; the bearings a few at a time.
  std::size_t sumDistancesToContour(const std::vector<Eigen::Vector2d>& queries, std::size_t stride,
                                    double radius, double cap, double& sum) const;

 private:
  static void checkBearingStep(double bearing_step);
  // Sets time, origin and the bins of points_.
  void index(TimeNs time, const Eigen::Vector2d& origin, double bearing_step);
  std::size_t binOf(const Eigen::Vector2d& point) const;
  // contourHit() of a query in bin `query_bin` (binOf(query)).
  bool contourHitIn(std::size_t query_bin, const Eigen::Vector2d& query, double radius,
                    ContourHit& hit) const;

  TimeNs time_ = 0;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();
  double bin_width_ = 1.0;
  double inverse_bin_width_ = 1.0;
  std::vector<Eigen::Vector2d> points_;
  std::vector<std::uint32_t> bin_begin_;  // points of bin b: by_bin_[bin_begin_[b] .. bin_begin_[b+1])
  std::vector<std::uint32_t> by_bin_;
  std::vector<Eigen::Vector2d> binned_;  // points_[by_bin_[k]]: the bins' points in one array
  std::vector<std::uint32_t> bin_of_;    // index()'s: each point's bin (kept for the storage)
  bool indexed_ = true;                  // the bins above are points_'s
};

/// A corrected scan placed with `laser`, the laser's pose in the fixed frame at its reference time;
/// every `stride`-th return kept (the contour's join distance grows with it). `bearing_step` [rad] the
/// scan's |angle_increment|.
PlacedScan placeCorrected(const DeskewedScan& corrected, const mrpt::poses::CPose3D& laser,
                          double bearing_step, std::size_t stride = 1);
/// The same into `placed`, reusing its storage (PlacedScan::assign(); `indexed` as there).
void placeCorrected(const DeskewedScan& corrected, const mrpt::poses::CPose3D& laser, double bearing_step,
                    std::size_t stride, PlacedScan& placed, bool indexed = true);
/// A raw scan placed with `laser`, the laser's pose at `time` [ns]: every return drawn as if measured
/// then (what a consumer that does not deskew sees); every `stride`-th return kept, as placeCorrected().
PlacedScan placeRaw(const PlanarScan& scan, const mrpt::poses::CPose3D& laser, TimeNs time,
                    std::size_t stride = 1);

/// The k-th of `count` indices spread evenly over [0, size), nearest first: 0, ..., size - 1.
inline std::size_t spreadIndex(std::size_t k, std::size_t count, std::size_t size) {
  return count <= 1 ? 0 : k * (size - 1) / (count - 1);
}

/// The measure's constants.
struct ConsistencyConfig {
  /// [m] a point with no point of the other scan this near along its ray is outside the overlap
  double overlap_radius = 0.5;
  /// [m] a point-to-line distance counts at most this much: a robust (truncated) mean
  double cap = 0.1;
  /// share of a scan's points that must overlap the other scan for the pair to count
  double min_overlap = 0.5;
  /// points of a scan used per pair at most, evenly spaced in beam order
  std::size_t max_points = 360;
};

/// The robust distance of `scan` to `other`: the mean over `scan`'s points within the overlap of
/// min(point-to-line distance, cap) [m]. `overlap` gets the share of the points used that overlap.
/// Returns NaN when no point overlaps.
double pairDistance(const PlacedScan& scan, const PlacedScan& other, const ConsistencyConfig& config,
                    double* overlap = nullptr);

/// Which pairs of scans to compare.
struct PairSelection {
  double max_interval = 10.0;  ///< [s] scans farther apart in time are not paired (odometry drifts)
  double max_baseline = 3.0;   ///< [m] nor are scans taken farther apart than this
  std::size_t partners = 8;    ///< each scan is paired with at most this many earlier ones, spread in time
};

/// The overlapping pairs (earlier, later) of `scans` (sorted by time; empty scans are skipped): for
/// each scan, up to `partners` earlier scans within max_interval and max_baseline, evenly spread over
/// them, kept when pairDistance finds at least min_overlap of the later scan in the overlap.
/// `eligible`, when not empty, says per scan whether it may take part.
std::vector<std::pair<std::size_t, std::size_t>> overlappingPairs(const std::vector<PlacedScan>& scans,
                                                                  const PairSelection& selection,
                                                                  const ConsistencyConfig& config,
                                                                  const std::vector<bool>& eligible = {});

/// A consistency over pairs, as reported: the mean of the pairs' robust distances and its spread.
struct ConsistencySummary {
  std::size_t pairs = 0;
  double mean = 0.0;    ///< [m] over the pairs (each pair's distance counts once)
  double spread = 0.0;  ///< [m] standard deviation of the pairs' distances
  double median = 0.0;  ///< [m]
};
/// Summarises per-pair distances (NaNs, pairs without overlap, are left out).
ConsistencySummary summarize(const std::vector<double>& pair_distances);

}  // namespace lidar_deskew::core
