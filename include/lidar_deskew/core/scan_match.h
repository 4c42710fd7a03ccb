// A free rigid match of two planar scans, and what it tells about a correction without odometry
// between the scans (docs/CALIBRATION.md, "Shapes"): how well scans a short time apart whose turn
// differs align, raw against corrected, and whether tf's rotation between consecutive scans is the one
// the scans show. ROS-free.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <Eigen/Core>

#include <cstddef>
#include <deque>
#include <string>
#include <vector>

#include "lidar_deskew/core/consistency.h"
#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/scan.h"

namespace lidar_deskew::core {

/// A planar rigid transform: p' = Rot(yaw) p + (x, y).
struct Pose2d {
  double x = 0.0;    ///< [m]
  double y = 0.0;    ///< [m]
  double yaw = 0.0;  ///< [rad]
  Eigen::Vector2d apply(const Eigen::Vector2d& point) const;
  /// this (+) other: first `other`, then this.
  Pose2d compose(const Pose2d& other) const;
};

/// The matcher's constants.
struct ScanMatchConfig {
  /// [rad] the coarse search tries rotations within +-this of the guess's ...
  double rotation_search = 0.8;
  /// [rad] ... this far apart, each followed by a few iterations from the guess's translation
  double rotation_step = 0.035;
  std::size_t coarse_iterations = 4;
  std::size_t coarse_points = 60;  ///< moving points per coarse candidate, evenly spread
  std::size_t max_points = 240;    ///< moving points in the refinement, evenly spread
  /// [m] correspondence radius at the start; it shrinks by a third per iteration down to final_radius
  double radius = 1.0;
  double final_radius = 0.3;
  /// [m] scale of the robust (Cauchy) kernel at the end; a quarter of the radius before
  double kernel = 0.03;
  std::size_t iterations = 40;  ///< refinement iterations at most
  double tolerance = 1e-7;      ///< [m, rad] a step smaller than this ends the refinement
  /// The aligned distance reported: ConsistencyConfig's robust point-to-line mean (cap 0.1 m) over the
  /// moving points within its overlap radius of the reference.
  ConsistencyConfig score{0.3, 0.1, 0.5, 360};
};

/// The result of matchScans().
struct ScanMatch {
  bool valid = false;   ///< enough correspondences at the end (a third of the moving points used)
  Pose2d pose;          ///< moving frame -> reference frame
  double distance = 0;  ///< [m] aligned distance (ScanMatchConfig::score); NaN when none overlaps
  double overlap = 0;   ///< share of the moving points within the score's overlap radius
  std::size_t iterations = 0;
};

/// Aligns `moving` (points [m] in its own frame, in beam order) to `reference` (a scan in its frame,
/// origin() the laser there): point-to-line ICP with a Cauchy kernel onto reference's contour
/// (PlacedScan::contourHit), after a coarse search over rotations round `guess`. The guess need not be
/// close: rotations within rotation_search and translations within about the radius are found.
ScanMatch matchScans(const PlacedScan& reference, const std::vector<Eigen::Vector2d>& moving,
                     const Pose2d& guess, const ScanMatchConfig& config = ScanMatchConfig());

/// What the shape measure and the rotation check do.
struct ShapeConfig {
  ScanMatchConfig match;
  double max_interval = 1.5;         ///< [s] pairs of scans at most this far apart
  double min_turn_difference = 0.3;  ///< [rad/s] whose turn rates (from scan matching) differ this much
  std::size_t partners = 3;          ///< later partners per scan at most, spread in time
  std::size_t max_pairs = 300;       ///< pairs at most, spread evenly over the recording
  double min_overlap = 0.5;          ///< a pair counts when both matches overlap this much, raw and corrected
  double turning_rate = 0.3;         ///< [rad/s] consecutive scans turn when tf or the match says so
  std::size_t min_pairs = 10;        ///< fewer pairs (or turning consecutive pairs): no verdict
  double max_lag = 0.5;              ///< [s] tf's rotation is also compared shifted by up to this ...
  double lag_step = 0.01;            ///< [s] ... in these steps
  /// Verdicts: tf's rotation does not fit when the scale is outside [1/max_scale_error, max_scale_error]
  /// or the correlation below min_correlation; correction makes shapes worse when the ratio exceeds
  /// max_ratio.
  double max_scale_error = 1.25;
  double min_correlation = 0.8;
  double max_ratio = 1.0;
};

/// Scans a short time apart whose turn differs, aligned by matchScans(), raw and corrected.
struct ShapeRatio {
  std::size_t pairs = 0;
  double raw = 0.0;        ///< [m] median aligned distance of the raw scans (every beam at its stamp)
  double corrected = 0.0;  ///< [m] ... of the corrected ones
  double ratio = 0.0;      ///< corrected / raw (NaN without pairs): below 1, correction sharpens shapes
  double ratio_low = 0.0, ratio_high = 0.0;  ///< quartiles of the pairs' own ratios: the spread
};

/// The rotation scan matching sees between consecutive raw scans against tf's (the laser's yaw between
/// the middles of their sweeps, where a raw scan's rotation is seen): the least-squares scale of
/// matched on tf, and their correlation.
struct RotationAgreement {
  std::size_t pairs = 0;          ///< consecutive pairs matched
  std::size_t turning_pairs = 0;  ///< of which tf or the match turns at ShapeConfig::turning_rate or more
  double scale = 0.0;             ///< matched = scale x tf (through 0); NaN without turning pairs
  double correlation = 0.0;       ///< Pearson's, over the matched pairs; NaN without turning pairs
  /// [s] tf shifted by this (its rotation between those times + lag), within +-ShapeConfig::max_lag,
  /// correlates best with the matched rotation: a clock or timing offset between tf and the scans lowers the
  /// scale and the correlation at lag 0, not at this one. NaN without turning pairs.
  double lag = 0.0;
  double lag_scale = 0.0, lag_correlation = 0.0;  ///< scale and correlation at that lag
};

/// The scans, the motion and the mount, with the consecutive matches done once; shapes under any timing.
class ShapeCheck {
 public:
  /// `scans` sorted by stamp; `motion` the base's (fixed -> base), `mount` base -> laser. Matches each
  /// scan to the one before (less than max_interval earlier), raw, without any guess (so tf does not
  /// enter), compares their rotations with tf's (where tf covers both) under the message's timing, and
  /// chooses the pairs by the matched turn rates. Throws InvalidInput when the scans are not sorted.
  ShapeCheck(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount, const MotionSource& motion,
             const ShapeConfig& config = ShapeConfig());
  /// The rotation agreement with tf's rotation between the middles of consecutive scans' sweeps under
  /// the message's own timing (TimingConfig()).
  const RotationAgreement& rotation() const { return rotation_; }
  /// ... under `timing` (a time_offset moves the sweeps; a scan whose timing cannot be resolved: its
  /// stamp + time_offset).
  RotationAgreement rotation(const TimingConfig& timing) const;
  /// The pairs (earlier, later) the shape ratio uses.
  const std::vector<std::pair<std::size_t, std::size_t>>& pairs() const { return pairs_; }
  /// The shape ratio with the scans corrected under `timing` and `deskew`.
  ShapeRatio shapes(const TimingConfig& timing, const DeskewConfig& deskew = DeskewConfig()) const;

 private:
  // [ns] the middle of scan i's sweep under `timing`: where a raw scan's rotation is seen
  TimeNs middleTime(std::size_t i, const TimingConfig& timing) const;

  std::vector<PlanarScan> scans_;
  mrpt::poses::CPose3D mount_;
  const MotionSource& motion_;
  ShapeConfig config_;
  std::vector<PlacedScan> raw_;         // each scan's returns in its laser frame
  std::vector<ScanMatch> to_previous_;  // scan i (moving) onto i - 1; invalid for none
  RotationAgreement rotation_;
  std::vector<std::pair<std::size_t, std::size_t>> pairs_;
  std::vector<ScanMatch> raw_matches_;  // per pair
};

/// The verdicts in words, each with its figure; empty when shapes improve and tf's rotation fits (or
/// when there are too few pairs to say): "tf's rotation does not fit the scans: scan matching sees
/// 0.41x tf's rotation between consecutive scans (correlation 0.97, 120 pairs, 80 turning)" (and,
/// when tf read at another lag fits, "; tf read at the scans' times -150 ms fits (0.98x, correlation
/// 0.98): ..."), "correction makes shapes worse than raw: aligned distance 1.27x raw (quartiles
/// 1.02-1.51, 80 pairs)".
std::vector<std::string> shapeWarnings(const ShapeRatio& shapes, const RotationAgreement& rotation,
                                       const ShapeConfig& config = ShapeConfig());

/// What checkShapes() finds: the shapes and tf's rotation under one timing, and the verdicts.
struct ShapeVerdict {
  ShapeRatio shapes;
  RotationAgreement rotation;         ///< under the same timing (ShapeCheck::rotation(timing))
  std::vector<std::string> warnings;  ///< shapeWarnings(): empty when nothing is wrong (or too few pairs)
};
/// One call for one timing (deskew_calibrate's check of its result before writing it): ShapeCheck over
/// `scans` (sorted by stamp), then its shapes and rotation under `timing`, and the warnings. To score
/// several timings on one recording, build one ShapeCheck and call shapes() per timing (the
/// consecutive matches and the pairs are done once).
ShapeVerdict checkShapes(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount,
                         const MotionSource& motion, const TimingConfig& timing,
                         const DeskewConfig& deskew = DeskewConfig(),
                         const ShapeConfig& config = ShapeConfig());

/// The live node's check that tf's rotation fits the scans (docs/CALIBRATION.md, "Shapes"): now and
/// then a scan is matched, raw and with no guess, to the one just before it, and the rotation seen is
/// compared with tf's between their sweeps' middles under the configured timing. Cheap: one match (about
/// a millisecond) per `interval` of scans.
struct RotationMonitorConfig {
  ShapeConfig shape;          ///< the matcher, the turning rate and the verdict's bounds and min_pairs
  double interval = 2.0;      ///< [s] at most one pair this often
  std::size_t history = 200;  ///< the newest pairs kept
};
class RotationMonitor {
 public:
  explicit RotationMonitor(const TimingConfig& timing,
                           const RotationMonitorConfig& config = RotationMonitorConfig());
  /// Offers the next scan of the stream (each one, in stamp order; `mount` base -> laser, `motion`
  /// covering its sweep). When `interval` has passed since the last pair and the scan before it came at
  /// most ShapeConfig::max_interval earlier, matches the two and compares with tf. Returns whether it
  /// matched (did the work). A scan whose timing or tf fails is skipped.
  bool add(const PlanarScan& scan, const mrpt::poses::CPose3D& mount, const MotionSource& motion);
  /// Scale and correlation over the pairs kept (no lag search: lag fields NaN).
  RotationAgreement agreement() const;
  /// shapeWarnings() on the agreement: empty when it fits or too few pairs turn.
  std::vector<std::string> warnings() const;
  /// Forgets the pairs and the previous scan; `timing` from now on.
  void reset(const TimingConfig& timing);

 private:
  TimingConfig timing_;
  RotationMonitorConfig config_;
  PlanarScan previous_;
  bool has_previous_ = false;
  TimeNs last_pair_ = 0;
  bool has_pair_ = false;
  struct Pair {
    double matched;  // [rad]
    double told;     // [rad] tf's
    bool turning;
  };
  std::deque<Pair> pairs_;
};

}  // namespace lidar_deskew::core
