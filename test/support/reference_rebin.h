// Test support: the re-binner as it was before the rewrite of issue 35 (a copy of core::ScanRebinner at
// that commit), frozen, so that the old-against-new harness (test/core/test_rebin_reference.cpp) and
// BM_RebinReference compare today's core::ScanRebinner with it. Do not change its behaviour: it is the
// reference.
#pragma once

#include <cstddef>
#include <cstdint>
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

  /// What core::ScanRebinner::rebin did before issue 35 (its contract is in core/rebin.h).
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

  // The steps of rebin(), in order (checking the grid is a file-local function in rebin.cpp). Each is one
  // pass over the points or links; square roots, bearings and divisions only where a rule needs them.
  /// Recomputes ray_cos_ / ray_sin_ (and the bins) when `grid` differs from the one they were made for.
  void updateRays(const core::AngleGrid& grid);
  /// One pass over the points: fills point_ (x, y, the running bin positions, next: the neighbouring
  /// point or kNoPoint, and each point's distance from the line through its neighbours as cross, length2;
  /// ranges and bearings come when asked for) and joined_ (close enough for one contour); throws
  /// InvalidInput("points") for a non-finite point.
  void readPoints(const Points& points, const BinSweep& sweep);
  /// Fills flat_: points that lie on the line through their two joined neighbours, within a tolerance
  /// set from the scan's own noise (the median distance of such points from that line).
  void findFlatPoints();
  /// Fills link_ (and corners) from joined_, flat_ and the geometry of the neighbouring segments; the
  /// links that are neither a surface nor a corner wait as kStep for traceContours().
  void classifyLinks(const BinSweep& sweep);
  /// One pass over the links: tells each waiting link a depth step, a chord or nothing, and offers every
  /// bin the crossings of its ray with the contours (surfaces, corners, steps); then the contour ends.
  void traceContours(const Points& points, const BinSweep& sweep);
  /// Writes the nearest crossing of every bin to `out`, `no_return` where none crossed, and leaves every
  /// bin empty for the next scan.
  void writeNearestCrossings(float no_return, core::RebinnedScan& out);

  // Used by the steps; inline (defined and used only in rebin.cpp) to keep the per-bin loops in one piece.
  /// [m] point j's range, [rad] its bearing (fastAtan2), computed on first use in a scan.
  inline double rangeOf(std::size_t j);
  inline double bearingOf(std::size_t j);
  /// [m] point j's distance from the line through its neighbours (which it has, not on one point).
  inline double residual(std::size_t j) const;
  /// [m] the core::RebinConfig gap for points a and b (at the larger of their ranges; a == b for a lone
  /// point).
  inline double joinGap(std::size_t a, std::size_t b, double abs_increment);
  /// Whether neighbours a and b, farther apart than the gap, can still make one surface (when one of them
  /// is flat) or a corner's wall: at most kMaxStepBins apart in bearing and a few gaps apart in distance
  /// (a wall at a grazing angle), and the scan's flat tolerance within kStepErrorBudget (with more noise,
  /// "flat" is no evidence).
  inline bool nearlyJoined(std::size_t a, std::size_t b, const BinSweep& sweep);
  /// What a waiting (kStep) link j is: a depth step when its farther point continues a surface on its
  /// other side and that continuation is sure; else kChord when joined, kNone when not.
  inline Link resolveStep(std::size_t j, const BinSweep& sweep);
  /// Whether a step's far contour (its end point `far`, the point `beyond` before it on that contour) can
  /// be continued behind `near` within kStepErrorBudget given the scan's noise (flat_tolerance_).
  inline bool continuationIsSure(std::size_t near, std::size_t far, std::size_t beyond);
  /// The point before j on its contour side (j's predecessor whose next is j), or kNoPoint.
  inline std::size_t previous(std::size_t j) const;
  /// Whether the corner of the line through (a0, a) and the line through (b, b1) lies between a and b.
  inline bool findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1, double& corner_x,
                         double& corner_y) const;
  /// The rays for running bin positions, by value (defined in rebin.cpp): locate() and walk() there.
  struct Rays;
  Rays rays() const;
  /// A kCorner link j -> q: the two segments through its corner.
  inline void crossCorner(const Points& points, std::size_t j, std::size_t q, const BinSweep& sweep);
  /// The rays and the bins' nearest crossings, by value (defined in rebin.cpp): crossRays() there.
  struct Bins;
  Bins bins(const Points& points);
  /// The segment (ax, ay) -> (bx, by) at bearings [rad]: offers every bin whose ray crosses it (found by
  /// bearing: for grids without running positions, and segments a quarter turn wide or more).
  inline void crossSegmentByBearing(double ax, double ay, double a_bearing, float a_intensity, double bx,
                                    double by, double b_bearing, float b_intensity, const BinSweep& sweep);
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
  /// Whether bins are found by running positions (a grid of at most a turn, not too fine); then the rays
  /// go on past the grid's last bin to complete the turn: ray_count_ >= rays_grid_.count.
  bool running_ = false;
  std::size_t ray_count_ = 0;
  double direction_ = 1.0;                   // the sign of angle_increment
  std::vector<double> ray_cos_, ray_sin_;    // unit ray direction of every ray
  std::vector<double> side_cos_, side_sin_;  // the same times direction_ (for side())
  std::vector<double> best_range_;           // [m] nearest crossing per bin so far (+inf between scans)
  std::vector<float> best_intensity_;        // its intensity (0 between scans)
  bool with_intensities_ = false;            // the scan carries intensities
  bool bins_in_use_ = false;                 // between the first offer and writeNearestCrossings()
  /// What readPoints() finds of one corrected point, in one place (a per-point loop needs one pointer).
  struct PointState {
    double x, y;                 // [m] the corrected point
    double side_low, side_high;  // [m] side() of the rays at and after its running position
    double cross, length2;       // [m^2], [m^2] of its distance from its neighbours' line (length2 0: none)
    std::size_t position;        // its running bin position (kUnknown: not found)
    std::size_t next;            // the neighbouring point (beam index + 1), or kNoPoint
  };
  std::vector<PointState> point_;
  std::vector<double> range_, bearing_;      // [m], [rad] their polar form where computed (0: not yet)
  std::vector<char> joined_;                 // j and its next are close enough for one contour
  std::vector<char> flat_;                   // j lies on the line through its two joined neighbours
  std::vector<Link> link_;                   // what joins j and its next
  std::vector<double> corner_x_, corner_y_;  // [m] the corner of a kCorner link
  std::vector<std::uint32_t> candidates_;    // points whose distance from that line estimates the noise
  std::size_t candidate_count_ = 0;          // how many of candidates_ are set (it keeps its size)
  std::vector<double> noise_sample_;         // [m] scratch for the noise estimate
  std::vector<std::size_t> ends_;            // points where a contour ends (or a lone return)
  double flat_tolerance_ = 0.0;              // [m] of the last scan
};

}  // namespace lidar_deskew::test
