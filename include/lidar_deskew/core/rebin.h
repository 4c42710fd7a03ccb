// Re-binning a corrected scan onto the input's own angle grid, as rays (docs/DESIGN.md §4): gmapping, AMCL
// and costmaps need a LaserScan with a fixed grid and beam count.
#pragma once

#include <cstddef>
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

  /// Re-bins `corrected` (from ScanDeskewer::deskew on a scan with grid `grid`) onto `grid`:
  /// - consecutive points (beam indices i, i+1; for a full-circle grid also n-1, 0) closer than the
  ///   RebinConfig gap form a contour; a bin's range is where its ray meets a contour segment, with
  ///   the intensity interpolated along it;
  /// - at a contour's two ends the end segment's line is followed for up to half a bin beyond the end
  ///   point (so a contour covers as many bins as it has points); a lone point is a facet facing the
  ///   sensor, half a bin to each side;
  /// - where several contours cross a ray (a fast spin folds the scan over itself), the nearest wins;
  /// - a bin no contour crosses gets `no_return`.
  /// Writes `grid.count` ranges (and intensities when corrected.has_intensities, else none).
  /// Throws InvalidInput("angle_increment") for a zero or non-finite increment with more than one bin,
  /// InvalidInput("points") for a non-finite point (ScanDeskewer never makes one).
  void rebin(const DeskewedScan& corrected, const AngleGrid& grid, float no_return, RebinnedScan& out);

 private:
  class BinSweep;  // finds the bins whose rays lie in an angle interval (defined in rebin.cpp)
  using Points = std::vector<DeskewedPoint>;

  // The steps of rebin(), in order (checking the grid is a file-local function in rebin.cpp).
  /// Recomputes ray_cos_ / ray_sin_ when `grid` differs from the one they were computed for.
  void updateRays(const AngleGrid& grid);
  /// Starts every bin of the scan with no crossing: range +inf, intensity 0.
  void clearBins(std::size_t bin_count);
  /// Fills point_range_ / point_bearing_ with the points' polar form; throws InvalidInput("points") for a
  /// non-finite point.
  void computePolarPoints(const Points& points);
  /// Fills linked_to_next_: which consecutive points (beam indices i, i+1; for a full-circle grid also
  /// n-1, 0) are close enough to form a contour segment.
  void linkContourNeighbours(const Points& points, const BinSweep& sweep);
  /// Offers every bin the crossings of its ray with the contours: their segments, their ends extended by
  /// half a bin, and lone points as facets facing the sensor.
  void traceContours(const Points& points, const BinSweep& sweep);
  /// Writes the nearest crossing of every bin to `out`, `no_return` where none crossed.
  void writeNearestCrossings(bool has_intensities, float no_return, RebinnedScan& out) const;

  // Used by the steps; inline (defined and used only in rebin.cpp) to keep the per-bin loops in one piece.
  /// [m] the RebinConfig gap for points a and b (at the larger of their ranges; a == b for a lone point).
  inline double joinGap(std::size_t a, std::size_t b, double abs_increment) const;
  /// Whether points a and b are close enough to be on one surface (the larger range sets the gap).
  inline bool joined(const Points& points, std::size_t a, std::size_t b, double abs_increment) const;
  /// Contour segment a -> b: offers every bin whose ray crosses it, intensity interpolated along it.
  inline void crossSegment(const Points& points, std::size_t a, std::size_t b, const BinSweep& sweep);
  /// Contour end (or lone point) p: offers the bins within half a bin of p's bearing where their ray meets
  /// the line through p along (dx, dy), no farther than `reach` [m] from p.
  inline void extendEnd(const Points& points, std::size_t p, double dx, double dy, double reach,
                        const BinSweep& sweep);
  /// Keeps `range` [m] and `intensity` for `bin` when nearer than what the bin has so far.
  inline void offer(std::size_t bin, double range, float intensity);

  RebinConfig config_;
  AngleGrid rays_grid_;
  std::vector<double> ray_cos_, ray_sin_;  // unit ray direction of every bin
  std::vector<double> best_range_;         // [m] nearest crossing per bin so far
  std::vector<float> best_intensity_;
  std::vector<double> point_range_, point_bearing_;  // polar form of the corrected points
  std::vector<char> linked_to_next_;                 // point j and the next one form a contour segment
};

}  // namespace lidar_deskew::core
