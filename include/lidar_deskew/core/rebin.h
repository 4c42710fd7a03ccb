// Re-binning a corrected scan onto the input's own angle grid, as rays (docs/DESIGN.md §4): gmapping, AMCL
// and costmaps need a LaserScan with a fixed grid and beam count.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/scan.h"

namespace lidar_deskew::core {

/// When two corrected points with consecutive beam indices belong to one surface.
struct RebinConfig {
  /// [m] points closer than min_gap + gap_factor * range * |angle_increment| are joined into a contour
  /// (range: the larger of the two). gap_factor 5 joins walls seen up to ~78 deg off-normal.
  double min_gap = 0.05;
  double gap_factor = 5.0;

  /// Throws InvalidInput naming the field when negative or not finite.
  void validate() const;
};

/// The angle grid of a scan: bin b is the ray at angle_min + b * angle_increment [rad].
struct AngleGrid {
  float angle_min = 0.0f;
  float angle_increment = 0.0f;
  std::size_t count = 0;
};

/// A scan on a fixed angle grid: one range [m] per bin, and one intensity per bin when carried.
struct RebinnedScan {
  std::vector<float> ranges;
  std::vector<float> intensities;
};

/// The value the input used for "no return": the first beam's range that is not a return
/// (ReturnTest), or +inf when every beam is a return.
float noReturnValue(const PlanarScan& scan);

/// Re-bins corrected scans onto their angle grid. Keeps the ray directions of the last grid, so reuse
/// one instance per input stream. Not thread-safe.
class ScanRebinner {
 public:
  /// Throws InvalidInput when the config is invalid.
  explicit ScanRebinner(const RebinConfig& config = RebinConfig());

  /// Re-bins `corrected` (from ScanDeskewer::deskew on a scan with grid `grid`) onto `grid`; a bin's
  /// range is where its ray meets the corrected contour (docs/CORE.md "Re-binning onto the input grid"):
  /// - consecutive points (beam indices i, i+1; for a full-circle grid also n-1, 0) closer than the
  ///   RebinConfig gap are candidates for one contour segment. A segment is a surface (a bin's range is
  ///   where its ray meets it, intensity interpolated) when one of its points lies on the line through
  ///   its other neighbours (within a tolerance that follows the scan's own noise); a wall at a grazing
  ///   angle, its points farther apart than the gap, too, up to kFlatJoinGaps gaps, when that tolerance
  ///   is within kStepErrorBudget;
  /// - a corner: where the lines of the two neighbouring segments meet between the points' bearings
  ///   (and within two segment lengths of both), the rays between meet the two walls up to that corner
  ///   (a wall at a grazing angle, its returns farther apart than the gap, counts when the scan's noise
  ///   is within kStepErrorBudget and a third return lies on its line);
  /// - a depth step (a near contour ends, a far one continues behind it; joined or not): the rays
  ///   between see the far contour's line continued behind the near one's end (no farther than the far
  ///   point), never a chord through free space; the near contour is not extended towards it. Only where
  ///   the scan's noise keeps that continuation within kStepErrorBudget (rebin.cpp); else as below;
  /// - other contour ends (next to a beam without a return, or the scan's end) follow the end segment's
  ///   line for up to half a bin; a lone point is a facet facing the sensor, half a bin to each side;
  /// - where the scan's noise is within kStepErrorBudget (rebin.cpp), what the returns cannot tell is left
  ///   empty rather than guessed beyond 10 mm (kGuessBudget): an end or a facet reaches at most 10 mm
  ///   past its return (the surface may end there), and a chord longer than 20 mm (two returns on no
  ///   surface, corner or step the rules know: the surface between may be a corner half as deep) fills
  ///   no bin;
  /// - where several contours cross a ray (a fast spin folds the scan over itself), the nearest wins;
  /// - a bin no contour crosses gets `no_return`.
  /// Writes `grid.count` ranges (and intensities when corrected.has_intensities, else none).
  /// Throws InvalidInput("angle_increment") for a zero or non-finite increment with more than one bin,
  /// InvalidInput("points") for a non-finite point (ScanDeskewer never makes one).
  void rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return, RebinnedScan& out);

 private:
  class BinSweep;  // finds the bins whose rays lie in an angle interval (defined in rebin.cpp)
  struct Rays;     // the rays for running bin positions (defined in rebin.cpp: locate() there)
  using Points = std::vector<DeskewedPoint>;

  /// What joins point j to the next one (beam index + 1, or the full circle's wrap).
  enum class Link : unsigned char {
    kNone,     ///< not neighbours, or too far apart and no step to bridge: two contour ends
    kSurface,  ///< one surface: the segment between them (one of the two is a flat point)
    kChord,    ///< close, but neither flat, a corner nor a step: the segment between them
    kCorner,   ///< two walls meeting between them (at corner_x_ / corner_y_ [j])
    kStep,     ///< a depth step: the farther point's contour continues behind the nearer one
    kPending,  ///< neither flat nor joined as a surface yet: classifyRareLinks() decides
  };

  // The steps of rebin(), in order. The common case (points on surfaces, one ray between neighbours) runs
  // over plain arrays in loops of arithmetic and bytes that the compiler vectorises (decisions as masks,
  // runs of one-ray links found 8 link bytes at a time; on x86-64 the points read as SSE2 pairs, and
  // with GCC an AVX2 variant of each step, without FMA: the same rounding); bearings (atan2) only for the
  // rare links (corners, steps, grazing walls) and contour ends. Outputs in double (float's rounding moved
  // ranges across the 10 mm mark of the scan metrics); float, in 32-bit lanes, only for decisions it makes
  // exactly, with a guard band about each threshold where double decides (locatePoints()).
  /// Recomputes the rays when `grid` differs from the one they were made for.
  void updateRays(const AngleGrid& grid);
  /// Fills x_, y_ (and in float), scale_, range_, has_next_, position_ (the running bin positions),
  /// joined_, the residuals and the noise candidates;
  /// throws InvalidInput("points") for a non-finite point.
  void readPoints(const Points& points, const BinSweep& sweep);
  /// position_ and near_ray_ of every point (readPoints()).
  void locatePoints(const Rays& rays);
  /// The scan's flat tolerance (from the median residual) and link_: surfaces where one of a joined pair is
  /// flat (on the line through its neighbours), kPending for the other neighbours, kNone for the rest.
  void classifyLinks();
  /// The pending links: a surface (a wall at a grazing angle), a corner, or kStep for traceContours().
  void classifyRareLinks(const BinSweep& sweep);
  /// One pass over the links: the crossings of every bin's ray with the contours (surfaces, corners,
  /// steps), then the contour ends.
  void traceContours(const Points& points, const BinSweep& sweep);
  /// Writes the nearest crossing of every bin to `out`, `no_return` where none crossed, and leaves every
  /// bin empty for the next scan.
  void writeNearestCrossings(float no_return, RebinnedScan& out);

  // The rare links' rules (rebin.cpp).
  /// [m] point j's range, [rad] its bearing (fastAtan2).
  inline double rangeOf(std::size_t j) const;
  inline double bearingOf(std::size_t j) const;
  /// The point after j (beam index + 1, or the full circle's wrap), or kNoPoint; the one before, or kNoPoint.
  inline std::size_t next(std::size_t j) const;
  inline std::size_t previous(std::size_t j) const;
  /// [m] the RebinConfig gap for points a and b (at the larger of their ranges; a == b for a lone point).
  inline double joinGap(std::size_t a, std::size_t b, double abs_increment) const;
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
  /// Whether the corner of the line through (a0, a) and the line through (b, b1) lies between a and b.
  inline bool findCorner(std::size_t a0, std::size_t a, std::size_t b, std::size_t b1, double& corner_x,
                         double& corner_y) const;
  /// A kCorner link j -> q: the two segments through its corner.
  inline void crossCorner(const Points& points, std::size_t j, std::size_t q, const BinSweep& sweep);
  Rays rays(double abs_increment) const;
  /// A segment's end: a point at running bin position `ray`, with side() of that ray and the next.
  struct RayPoint {
    double x, y;  // [m]
    std::int32_t ray;
    double low, high;  // [m]
    float intensity;
  };
  /// The segment a -> b (less than a quarter turn wide): offers the rays between their positions, and the
  /// ray at either end that the end lies on, intensity interpolated.
  inline void crossRays(const RayPoint& a, const RayPoint& b);
  /// Whether point j lies on its position's ray (bit 0) or the next (bit 1), within rounding; offers that
  /// ray point j's own range (where no segment through j crosses it).
  inline unsigned onRay(std::size_t j) const;
  inline void offerOwnRay(std::size_t j, const Points& points);
  /// The same for surface link a -> b, the common case, from onRay(); false (nothing done) when a point has
  /// no running position or the segment is a quarter turn wide or more.
  inline bool crossSurface(std::size_t a, std::size_t b, const Points& points);
  /// Offers `count` rays from `ray` on their crossing with the segment a -> b, intensity interpolated.
  inline void offerRays(std::int32_t ray, std::int32_t count, double ax, double ay, float a_intensity,
                        double bx, double by, float b_intensity);
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

  RebinConfig config_;
  AngleGrid rays_grid_;
  /// Whether bins are found by running positions (a grid of at most a turn, not too fine); then the rays
  /// go on past the grid's last bin to complete the turn: ray_count_ >= rays_grid_.count.
  bool running_ = false;
  std::size_t ray_count_ = 0;
  double direction_ = 1.0;                   // the sign of angle_increment
  // locatePoints() in float: whether, the grid's first ray's angle [rad] in [0, 2pi), 1 / |increment|,
  // the guard band [bins] about each ray, the last position [bins] not near the first ray.
  bool float_positions_ = false;
  float bearing_origin_ = 0.0f, bins_per_radian_ = 0.0f, position_guard_ = 0.0f, last_sure_bin_ = 0.0f;
  std::vector<double> ray_cos_, ray_sin_;    // unit ray direction of every ray (and kRayPadding copies)
  std::vector<double> side_cos_, side_sin_;  // the same times direction_ (for Rays::side())
  std::vector<double> best_range_;           // [m] nearest crossing per bin so far (+inf between scans)
  std::vector<float> best_intensity_;        // its intensity (0 between scans)
  std::vector<float> converted_;             // [m] the ranges in float (writeNearestCrossings())
  bool with_intensities_ = false;            // the scan carries intensities
  bool bins_in_use_ = false;                 // between the first offer and writeNearestCrossings()
  bool wraps_ = false;                       // the last point neighbours the first (a full circle)
  // Per point, in plain arrays.
  std::vector<double> x_, y_, scale_;      // [m] the corrected point, max(|x|, |y|)
  std::vector<float> x_float_, y_float_;   // [m] the same in float (locatePoints())
  std::vector<float> intensity_;           // the points' intensities, with_intensities_ (traceContours())
  std::vector<double> range_;              // [m] its range (rangeOf())
  std::vector<std::uint32_t> beam_;        // its beam index
  std::vector<double> cross_, length2_;    // [m^2] its distance from its neighbours' line as |cross| /
                                           // sqrt(length2); cross infinite: no such line
  std::vector<std::int32_t> position_;     // its running bin position (negative: not found)
  std::vector<unsigned char> near_ray_;    // the position found by side() (near a ray): onRay() may hold
  std::vector<unsigned char> has_next_;    // j's next point is its neighbour (beam index + 1, or the wrap)
  std::vector<unsigned char> joined_;      // j and its next are close enough for one contour
  std::vector<double> join_test_;          // scratch
  std::vector<unsigned char> line_;        // scratch
  std::vector<unsigned char> flat_;        // j lies on the line through its two joined neighbours
  std::vector<unsigned char> candidate_;   // j's residual estimates the noise (both links joined); padded
  std::size_t candidate_count_ = 0;        // to whole words of 8 with 0
  std::vector<Link> link_;                   // what joins j and its next
  std::vector<unsigned char> run_kind_;      // what a run of surfaces does with link j (traceContours())
  std::vector<double> corner_x_, corner_y_;  // [m] the corner of a kCorner link
  std::vector<double> noise_sample_;         // [m] scratch for the noise estimate
  std::vector<double> noise_select_;         // scratch for its median
  std::vector<double> noise_bucket_;         // scratch: the sample's residuals in its median's bucket
  double noise_median_ = NAN;                // [m] of the last scan: the next one's first pivot
  std::vector<std::size_t> ends_;            // points where a contour ends (or a lone return)
  double flat_tolerance_ = 0.0;              // [m] of the last scan
};

}  // namespace lidar_deskew::core
