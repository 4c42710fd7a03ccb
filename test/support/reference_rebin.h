// Test support: the re-binner as it was before the one-pass rewrite (issue 25), frozen, so that the
// old-against-new harness (test/core/test_rebin_reference.cpp) and BM_RebinReference compare today's
// core::ScanRebinner with it. Do not change its behaviour: it is the reference.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"

namespace lidar_deskew::test {

/// Re-bins corrected scans onto their angle grid. Keeps the ray directions of the last grid, so reuse
/// one instance per input stream. Not thread-safe.
class ReferenceRebinner {
 public:
  /// Throws InvalidInput when the config is invalid.
  explicit ReferenceRebinner(const core::RebinConfig& config = core::RebinConfig());

  /// What core::ScanRebinner::rebin did before issue 25 (its contract is in core/rebin.h).
  void rebin(const core::DeskewedScan& corrected, const core::AngleGrid& grid, float no_return,
             core::RebinnedScan& out);

 private:
  class BinSweep;  // finds the bins whose rays lie in an angle interval (defined in rebin.cpp)
  using Points = std::vector<core::DeskewedPoint>;

  /// What joins point j to the next one (beam index + 1, or the full circle's wrap).
  enum class Link : unsigned char {
    kNone,     ///< not neighbours, or too far apart and no step to bridge: two contour ends
    kSurface,  ///< one surface: the segment between them (one of the two is a flat point)
    kChord,    ///< close, but neither flat, a corner nor a step: the segment between them
    kCorner,   ///< two walls meeting between them (at corner_x_ / corner_y_ [j])
    kStep,     ///< a depth step: the farther point's contour continues behind the nearer one
  };

  // The steps of rebin(), in order (checking the grid is a file-local function in rebin.cpp).
  /// Recomputes ray_cos_ / ray_sin_ when `grid` differs from the one they were computed for.
  void updateRays(const core::AngleGrid& grid);
  /// Starts every bin of the scan with no crossing: range +inf, intensity 0.
  void clearBins(std::size_t bin_count);
  /// Fills x_, y_, range_, bearing_ from the points; throws InvalidInput("points") for a non-finite point.
  void computePolarPoints(const Points& points);
  /// Fills next_ (the neighbouring point, or kNoPoint) and joined_ (close enough for one contour).
  void linkContourNeighbours(const Points& points, const BinSweep& sweep);
  /// Fills flat_: points that lie on the line through their two joined neighbours, within a tolerance
  /// set from the scan's own noise (the median distance of such points from that line).
  void findFlatPoints();
  /// Fills link_ (and corners) from joined_, flat_ and the geometry of the neighbouring segments.
  void classifyLinks(const BinSweep& sweep);
  /// Offers every bin the crossings of its ray with the contours: surfaces, corners, steps, ends.
  void traceContours(const Points& points, const BinSweep& sweep);
  /// Writes the nearest crossing of every bin to `out`, `no_return` where none crossed.
  void writeNearestCrossings(bool has_intensities, float no_return, core::RebinnedScan& out) const;

  // Used by the steps; inline (defined and used only in rebin.cpp) to keep the per-bin loops in one piece.
  /// [m] the RebinConfig gap for points a and b (at the larger of their ranges; a == b for a lone point).
  inline double joinGap(std::size_t a, std::size_t b, double abs_increment) const;
  /// Whether neighbours a and b, farther apart than the gap, can still make one surface (when one of them
  /// is flat) or a corner's wall: at most kMaxStepBins apart in bearing and a few gaps apart in distance
  /// (a wall at a grazing angle), and the scan's flat tolerance within kStepErrorBudget (with more noise,
  /// "flat" is no evidence).
  inline bool nearlyJoined(std::size_t a, std::size_t b, const BinSweep& sweep) const;
  /// Whether a step's far contour (its end point `far`, the point `beyond` before it on that contour) can
  /// be continued behind `near` within kStepErrorBudget given the scan's noise (flat_tolerance_).
  inline bool continuationIsSure(std::size_t near, std::size_t far, std::size_t beyond) const;
  /// The point before j on its contour side (j's predecessor whose next_ is j), or kNoPoint.
  inline std::size_t previous(std::size_t j) const;
  /// Whether the corner of the line through (a0, a) and the line through (b, b1) lies between a and b.
  inline bool findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1, double& corner_x,
                         double& corner_y) const;
  /// The segment (ax, ay) -> (bx, by) at bearings [rad]: offers every bin whose ray crosses it, intensity
  /// interpolated along it.
  inline void crossSegment(double ax, double ay, double a_bearing, float a_intensity, double bx, double by,
                           double b_bearing, float b_intensity, const BinSweep& sweep);
  /// The line through point p along (dx, dy): offers the bins within [low, low + width] [rad] where their
  /// ray meets it no farther than `reach` [m] from p and no nearer than `min_range` [m] (nor farther than
  /// `max_range` [m]) from the sensor;
  /// with max_slant > 0 also no farther along the line than max_slant times p's distance from the ray;
  /// with only_empty only bins nothing has reached yet.
  inline void extendLine(const Points& points, std::size_t p, double dx, double dy, double reach,
                         double min_range, double low, double width, const BinSweep& sweep,
                         double max_slant = 0.0, bool only_empty = false,
                         double max_range = std::numeric_limits<double>::infinity());
  /// Keeps `range` [m] and `intensity` for `bin` when nearer than what the bin has so far.
  inline void offer(std::size_t bin, double range, float intensity);

  static constexpr std::size_t kNoPoint = static_cast<std::size_t>(-1);

  core::RebinConfig config_;
  core::AngleGrid rays_grid_;
  std::vector<double> ray_cos_, ray_sin_;  // unit ray direction of every bin
  std::vector<double> best_range_;         // [m] nearest crossing per bin so far
  std::vector<float> best_intensity_;
  std::vector<double> x_, y_;                // [m] the corrected points
  std::vector<double> range_, bearing_;      // [m], [rad] their polar form
  std::vector<std::size_t> next_;            // the neighbouring point (beam index + 1), or kNoPoint
  std::vector<char> joined_;                 // j and next_[j] are close enough for one contour
  std::vector<char> flat_;                   // j lies on the line through its two joined neighbours
  std::vector<Link> link_;                   // what joins j and next_[j]
  std::vector<double> corner_x_, corner_y_;  // [m] the corner of a kCorner link
  std::vector<double> residuals_;            // [m] distance of flat_ candidates from their neighbours' line
  std::vector<double> noise_sample_;         // [m] scratch for the noise estimate
  double flat_tolerance_ = 0.0;              // [m] of the last scan
};

}  // namespace lidar_deskew::test
