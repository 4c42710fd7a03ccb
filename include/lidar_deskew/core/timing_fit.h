// Finding a planar LIDAR's timing from data (docs/CALIBRATION.md): the timing under which corrected
// scans agree best where they overlap, while the robot turns. deskew_calibrate and the node's live
// check use it. ROS-free.
#pragma once

#include <mrpt/poses/CPose3D.h>

#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lidar_deskew/core/consistency.h"
#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/core/scan_match.h"

namespace lidar_deskew::core {

struct TimingFitConfig {
  ConsistencyConfig consistency{0.5, 0.1, 0.5, 120};  ///< 120 points of a scan per pair: enough, 3x faster
  /// The coarse search's measure: the cap at the overlap radius widens the score's valley (a timing
  /// error of d moves points by turn rate x range x d; beyond the cap they stop counting more), fewer
  /// points per pair, and tf's straight line between its samples instead of the twist fit.
  ConsistencyConfig coarse_consistency{0.5, 0.5, 0.5, 60};
  PairSelection pairs;
  /// [rad/s] a scan turns when its base turns at least this fast over the sweep
  double turning_rate = 0.3;
  /// scans that must turn for the beam order and the period to be told
  std::size_t min_turning_scans = 10;
  /// overlapping pairs with a turning scan, likewise
  std::size_t min_turning_pairs = 20;
  /// overlapping pairs whose two scans' turn rates differ by at least turning_rate: the offset needs
  /// them (under one constant twist an offset moves every scan by the same rigid transform)
  std::size_t min_changing_pairs = 20;
  /// [s] the offset estimate's resolution: the fine search's step is at most 5 x this (a parabola
  /// through the best three refines it)
  double resolution = 0.0001;
  /// [s] the offset is searched first over +-max(search_range, search_periods x the period) ...
  double search_range = 1.0;
  double search_periods = 3.0;
  /// [s] ... and that window doubled while the best offset lies on its edge, up to +-this; a minimum
  /// still on the edge is no estimate
  double max_search_range = 4.0;
  /// [s] the coarse search's step, at most; and at most half the period
  double coarse_step = 0.01;
  /// pairs the coarse search scores at most, spread evenly over the recording (it only has to find
  /// the valley; the fine search scores every pair)
  std::size_t coarse_pairs = 500;
  /// [s] an estimate this close to "as the message says" (or to "stamped at the end") is snapped to it
  double snap = 0.0005;
  /// largest one-standard-deviation uncertainty of the offset, as a share of the sweep period, for an
  /// estimate to be trusted
  double max_uncertainty_share = 0.1;
  /// share of resamples that must prefer the chosen beam order (and period) for it to be told
  double min_confidence = 0.9;
  /// the coarse score's minimum must lie this share of its median below the median
  /// (TimingEstimate::curve_depth) for the timing to be told; below it the score is too flat
  double min_curve_depth = 0.05;
  /// [s] odometry whose samples lie at most this far apart (50 Hz, with jitter) is never blamed for an
  /// uncertain offset
  double fine_odometry_interval = 0.03;
  /// [s] the period, when the user gives it (0: from the message and the stamps)
  double given_period = 0.0;
  /// the beam order, when the user gives it (none: both are tried)
  std::optional<BeamOrder> given_order;
  std::size_t resamples = 200;  ///< bootstrap resamples for the uncertainties
  /// [s] the bootstrap draws blocks of consecutive scans this long (scans of one turn are not
  /// independent: their errors come from the same motion and odometry)
  double block_duration = 3.0;
  unsigned seed = 1;
};

/// One scan's turn and where it was taken: decides which scans and pairs can tell a timing.
struct ScanMotion {
  double turn_rate = 0.0;  ///< [rad/s] yaw change over the sweep / its duration
  double speed = 0.0;      ///< [m/s]
};

/// The scans of one sensor, the laser's mount and the base's motion, and the consistency of the
/// corrected scans under any timing. Pairs are chosen once, under the message's own timing, among
/// scans in which the base moves, so that every timing is scored on the same pairs.
class TimingFit {
 public:
  /// Keeps the scans that `motion` covers from the stamp to a period after it, and chooses the pairs
  /// (see shift()). A timing that shifts a scan beyond what the motion covers leaves the pairs with that
  /// scan unscored (see pairDistances).
  /// `nominal_period` [s] one revolution; 0 = from the stamps (the mean interval between consecutive
  /// scans, of those within 20 % of the median). Throws InvalidInput when no scan is left.
  TimingFit(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount, const MotionSource& motion,
            double nominal_period, const TimingFitConfig& config);

  /// Chooses the scans, their motions and the pairs anew as if every stamp were `offset` [s] later (the
  /// first beam at stamp + offset): what the constructor does with 0. The estimate calls it with its
  /// coarse result, so that the same scans and pairs are used however far the stamps are off.
  void shift(double offset);
  /// [s] the offset of the last shift()
  double shifted() const { return shift_; }

  std::size_t scanCount() const { return scans_.size(); }
  /// Scans left out because the motion does not cover them from the (shifted) stamp to a period after
  /// it: before the odometry's first sample or after its last.
  std::size_t leftOut() const { return all_scans_.size() - scans_.size(); }
  const std::vector<ScanMotion>& motions() const { return motions_; }
  const std::vector<std::pair<std::size_t, std::size_t>>& pairs() const { return pairs_; }
  std::size_t turningScans() const;
  const PlanarScan& scan(std::size_t i) const { return scans_[i]; }
  double nominalPeriod() const { return nominal_period_; }
  /// [s] the standard error of the nominal period when it came from the stamps; else 0
  double nominalPeriodSigma() const { return nominal_sigma_; }
  /// [s] the median over the scans of messagePeriod()
  double messagePeriod() const { return message_period_; }

  /// [s] The median over the scans of the longest interval between the motion's samples that overlaps
  /// the sweep (0 for a continuous motion source): the odometry's resolution in time.
  double odometryInterval() const { return odometry_interval_; }

  /// What place() makes of a scan (its `needed`): nothing, the whole, or its points only.
  enum Need : char { kLeftOut = 0, kPlaced = 1, kPointsOnly = 2 };
  /// The scans corrected under `timing` and placed in the fixed frame (empty where the timing is not
  /// valid for a scan or motion does not cover it). `placed`, when given, gets per scan whether it was
  /// placed. `coarse`: tf's straight line between samples instead of the default interpolation.
  /// `needed`, when given, says which scans to place (kLeftOut: left empty; kPointsOnly: not to be
  /// looked up in, PlacedScan::assign()).
  std::vector<PlacedScan> place(const TimingConfig& timing, std::vector<char>* placed = nullptr,
                                bool coarse = false, const std::vector<char>* needed = nullptr) const;
  /// The same into `scans`, reusing its scans' storage (PlacedScan::assign()): a search that places
  /// every scan at each of hundreds of timings passes the same vector each time.
  void place(const TimingConfig& timing, std::vector<PlacedScan>& scans, std::vector<char>* placed = nullptr,
             bool coarse = false, const std::vector<char>* needed = nullptr) const;
  /// The raw scans (every beam at the stamp) placed in the fixed frame; empty where the motion does not
  /// cover the stamp.
  std::vector<PlacedScan> placeRaw() const;
  /// pairDistance() of every pair under `timing` [m]; NaN where a scan could not be placed.
  std::vector<double> pairDistances(const TimingConfig& timing) const;
  std::vector<double> pairDistances(const std::vector<PlacedScan>& placed) const;
  /// Per pair, the distance under `timing` [m] (NaN: no overlap) and in `scored` whether the motion
  /// placed both scans (0: the pair cannot be scored under this timing). `coarse`: the coarse search's
  /// measure (TimingFitConfig::coarse_consistency, tf's straight line between samples) on its pairs
  /// only (TimingFitConfig::coarse_pairs; the others unscored). `placed`: the scans placed, reused from
  /// call to call (pass the same vector each time; its contents are of no further use).
  std::vector<double> pairDistances(const TimingConfig& timing, std::vector<char>& scored, bool coarse,
                                    std::vector<PlacedScan>& placed) const;
  /// The indices in pairs() of the pairs the coarse search scores, in order.
  std::vector<std::size_t> coarsePairs() const;

 private:
  // Scan i corrected under `timing` into `result`; false (`result` emptied) where it cannot be placed.
  bool placeOne(std::size_t i, const TimingConfig& timing, ScanDeskewer& deskewer, DeskewedScan& corrected,
                PlacedScan& result, std::size_t stride = 1, bool indexed = true) const;

  std::vector<PlanarScan> all_scans_;  // sorted by stamp
  std::vector<PlanarScan> scans_;      // those the motion covers under the shift
  double shift_ = 0.0;
  mrpt::poses::CPose3D mount_;
  const MotionSource& motion_;
  double nominal_period_;
  double nominal_sigma_ = 0.0;
  double message_period_ = 0.0;
  double odometry_interval_ = 0.0;
  TimingFitConfig config_;
  std::vector<ScanMotion> motions_;
  std::vector<std::pair<std::size_t, std::size_t>> pairs_;
  std::vector<char> coarse_pairs_;  // [pair] scored by the coarse search
  // [scan] Need: the earlier scan of a pair is looked up in (kPlaced), the later one's points measured
  std::vector<char> coarse_scans_;  // ... of the coarse pairs (kLeftOut: in none)
  std::vector<char> fine_scans_;    // ... of all pairs (kPointsOnly: also in none)
};

/// Why a part of the timing could not be told (TimingEstimate::cause).
enum class TimingCause {
  kNone,               ///< everything was told
  kTooFewPairs,        ///< too few overlapping pairs of scans in which the base moves
  kTooLittleTurning,   ///< too few scans turn (the beam order and the period need turning scans)
  kTurningTooUniform,  ///< scans turn, but overlapping scans turn alike: a constant twist hides an offset
  kOdometryTooCoarse,  ///< the odometry's samples lie farther apart than a sweep: the offset is blurred
  kNoClearMinimum,     ///< the score has no clear minimum: the estimate is too uncertain or on the edge
  kWorseThanRaw,       ///< corrected with the best timing, scans agree less than raw ones
  kTooFlat,            ///< the score barely changes with the offset over the whole range searched
  kUndecided,          ///< the recording turns enough, yet the beam order or the period is undecided
};
/// A short name of the cause, e.g. "turning too uniform".
std::string toString(TimingCause cause);

/// What deskew_calibrate reports. Three outcomes: everything told (`told` and `offset_told`); the
/// beam order and the period told but not the offset (`told`, not `offset_told`: the timing keeps the
/// message's offset, `why` says why the offset is not seen); nothing told (not `told`, `why`).
struct TimingEstimate {
  bool told = false;         ///< the beam order and the period are told: `timing` may be written
  bool offset_told = false;  ///< the offset is told too; otherwise `timing` keeps the message's
  TimingCause cause = TimingCause::kNone;
  std::string why;            ///< what could not be told and why, in words (empty when everything was)
  TimingConfig timing;        ///< the estimate, as parameters (stamp_at start unless snapped to end)
  double time_offset = 0.0;   ///< [s] first beam - stamp, the best found, before snapping (NaN: no search)
  double offset_sigma = 0.0;  ///< [s] one standard deviation (block bootstrap over scans)
  double search_range = 0.0;  ///< [s] the offset was searched over +-this round the stamp
  bool on_edge = false;       ///< the best offset lay on the search window's edge (no estimate)
  /// How far the coarse score's minimum over the whole range searched lies below its median, as a share
  /// of the median (the chosen order and period, first search): 0 = flat, the offset cannot be told
  double curve_depth = 0.0;
  double order_confidence = 0.0;   ///< share of resamples that prefer the estimated beam order
  double period_confidence = 1.0;  ///< ... the chosen period, where there were two candidates
  double period = 0.0;             ///< [s] the revolution period used
  double period_sigma = 0.0;       ///< [s] when estimated; 0 when the message's was kept
  bool period_estimated = false;   ///< the message's period was 0 or disagreed with the data
  bool period_given = false;       ///< the period was the user's (TimingFitConfig::given_period)
  double message_period = 0.0;     ///< [s] the message's own (time_increment, else scan_time); 0 = none
  double sweep = 0.0;              ///< [s] first to last beam under `period` (when told)
  bool changed = false;            ///< differs from the message's own timing
  std::size_t scans = 0, pairs = 0, turning_scans = 0, turning_pairs = 0;
  std::size_t changing_pairs = 0;  ///< pairs whose scans' turn rates differ by turning_rate or more
  std::size_t block_scans = 0;     ///< scans per bootstrap block
  std::size_t left_out = 0;        ///< scans the motion does not cover (TimingFit::leftOut())
  double fastest_turn = 0.0;       ///< [rad/s]
  double turning_rate = 0.0;       ///< [rad/s] TimingFitConfig::turning_rate, as used
  double odometry_interval = 0.0;  ///< [s] TimingFit::odometryInterval()
  ConsistencySummary raw;          ///< every beam at the stamp
  ConsistencySummary before;       ///< corrected with the message's timing (as the node does by default)
  ConsistencySummary after;        ///< corrected with the estimate (when told)
  /// The chosen beam order's and period's score [m] against the offset [s]: the coarse search's (its
  /// measure) and the fine one's.
  std::vector<std::pair<double, double>> coarse_curve, fine_curve;
};

/// Estimates time_offset, beam_order and, where the message's is 0 or disagrees with the data, the
/// period, from `fit`: per beam order and candidate period (the message's and `fit`'s nominal one) a
/// coarse search of the offset over +-max(search_range, search_periods periods), widened while the best
/// lies on the edge, and a fine one round the best; uncertainties by a bootstrap over blocks of
/// consecutive scans. When the coarse search finds the offset, `fit` is shift()ed to it and searched
/// again (the scans and pairs then do not depend on how far the stamps were off). See
/// docs/CALIBRATION.md.
TimingEstimate estimateTiming(TimingFit& fit, const TimingFitConfig& config);

/// The live node's check that its timing fits (docs/CALIBRATION.md): each scan it is given is corrected
/// under the configured timing and a few alternatives (stamp_at flipped, beam_order flipped, both, the
/// stamp in the middle of the sweep) and compared with up to `partners` scans given before it within
/// `history`; pairs in which either scan turns count towards a running consistency per timing. A scan
/// keeps `beams` of its corrected returns (every k-th): a check costs about 0.1-0.3 ms.
/// The shape score, which odometry between scans cannot spoil: the checked scan is also aligned by
/// matchScans() with the nearest scan offer()ed before it, at most shape.max_interval earlier, whose turn
/// rate differs by shape.min_turn_difference, raw (every beam at its stamp: what the node would publish
/// without correcting) and under every timing; it decides whether correction makes shapes worse than raw.
struct TimingCheckConfig {
  ConsistencyConfig consistency{0.5, 0.1, 0.5, 90};  ///< fewer points per pair than offline
  std::size_t beams = 90;  ///< every k-th return of a corrected scan, at most this many, is compared
  double history = 30.0;   ///< [s] earlier scans kept as partners (checked scans come seconds apart)
  std::size_t partners = 4;
  double turning_rate = 0.3;   ///< [rad/s] a pair counts when either scan turns this fast
  std::size_t min_pairs = 20;  ///< counted pairs before any verdict
  double margin = 0.9;         ///< "markedly better": a mean below margin x the configured timing's
  double min_win_share = 0.6;  ///< ... that also wins this share of the pairs
  /// The shape pairs' rules (max_interval, min_turn_difference, min_overlap) and the matcher. The raw
  /// pair is matched from tf's relative pose with a coarse search of +-0.4 rad (the partner is the nearest
  /// whose turn differs: a short turn apart); each timing's from the raw match's pose, +-refine_search.
  ShapeConfig shape = [] {
    ShapeConfig config;
    config.match.rotation_search = 0.4;
    config.match.rotation_step = 0.05;
    config.match.coarse_iterations = 2;
    config.match.coarse_points = 20;
    config.match.iterations = 12;
    return config;
  }();
  double refine_search = 0.0;  ///< [rad]
  std::size_t refine_iterations = 8;
  std::size_t min_shape_pairs = 10;  ///< shape pairs before the shape score says anything
  std::size_t shape_history = 100;   ///< the newest shape pairs kept
  std::size_t offered = 128;         ///< scans kept as shape partners at most (and shape.max_interval + 1 s)
};

class TimingCheck {
 public:
  enum class State {
    kUnknown,       ///< not enough turning seen yet
    kFits,          ///< no alternative fits markedly better
    kBetter,        ///< `better` fits markedly better than the configured timing
    kWorseThanRaw,  ///< raw scans align markedly better than corrected ones, under every timing
  };
  struct Verdict {
    State state = State::kUnknown;
    std::size_t pairs = 0;    ///< pairs counted
    double configured = 0.0;  ///< [m] mean pair distance under the configured timing
    double best = 0.0;        ///< [m] ... under the best alternative
    std::string best_name;    ///< the best alternative as parameters, e.g. "stamp_at: end"
    /// The shape score (medians over the shape pairs kept; 0 without pairs): aligned distances [m].
    std::size_t shape_pairs = 0;
    double shape_raw = 0.0;         ///< [m] raw: every beam at its stamp
    double shape_configured = 0.0;  ///< [m] under the configured timing
    double shape_best = 0.0;        ///< [m] under the alternative that aligns best
    std::string shape_best_name;
    std::string message;
  };

  explicit TimingCheck(const TimingConfig& configured, const TimingCheckConfig& config = TimingCheckConfig());
  /// Starts over with `configured` (the parameters changed, or time jumped).
  void reset(const TimingConfig& configured);
  /// Keeps `scan` (each scan of the stream, in stamp order: a copy, no other work) as a possible shape
  /// partner of a scan checked later.
  void offer(const PlanarScan& scan);
  /// Adds one scan (corrected under the configured timing already). Scans are used in order, each once
  /// `motion` covers it under every alternative (stamp_at flipped from end to start reaches a sweep past
  /// the last beam): now, or at a later add() or tryPending(); at most 3 wait. Returns true when a scan
  /// was used (at most one per call).
  bool add(const PlanarScan& scan, const mrpt::poses::CPose3D& mount, const MotionSource& motion);
  /// Uses the waiting scan if `motion` now covers it (call when tf arrives). Returns true when used. A
  /// scan `motion` will never cover is left out: one whose configured sweep's start it no longer covers
  /// (tf keeps a limited past), or one with a scan more than 1 s newer waiting behind it.
  bool tryPending(const MotionSource& motion);
  bool waiting() const { return !pending_.empty(); }
  Verdict verdict() const;
  /// Scans used so far (since the last reset).
  std::size_t scans() const { return scans_; }

 private:
  struct Entry {
    TimeNs time;
    double turn_rate;                // [rad/s] signed
    std::vector<PlacedScan> placed;  // per timing, configured first
  };
  // The shape pair of a just-placed `entry` (`scan` itself) with the nearest offered scan before it
  // whose turn differs, if any.
  void addShapePair(const PlanarScan& scan, const mrpt::poses::CPose3D& mount, const Entry& entry,
                    TimeNs middle, std::size_t stride, const MotionSource& motion);
  // Every k-th return of `scan` is placed: at most config_.beams.
  std::size_t strideFor(const PlanarScan& scan) const;

  TimingCheckConfig config_;
  std::vector<std::pair<std::string, TimingConfig>> timings_;  // configured first; built per scan
  TimingConfig configured_;
  std::vector<Entry> history_;
  struct Pending {
    PlanarScan scan;
    mrpt::poses::CPose3D mount;
  };
  std::deque<Pending> pending_;    // oldest first, at most 3
  std::vector<double> sums_;       // [m] per timing
  std::vector<std::size_t> wins_;  // pairs in which the timing beat the configured one
  std::size_t pairs_ = 0;
  std::size_t scans_ = 0;
  std::deque<PlanarScan> offered_;               // oldest first
  std::deque<std::vector<double>> shape_pairs_;  // [m] per pair: raw, then per timing (configured first)
  ScanDeskewer deskewer_;
  DeskewedScan corrected_;
};

/// [rad/s] The base's signed yaw change from `begin` to `end` [ns] (end > begin) over that time, on
/// the shorter way round. Throws MotionUnavailable where `motion` does not cover either end.
double turnRate(const MotionSource& motion, TimeNs begin, TimeNs end);

/// The revolution period the message's fields give for `scan`: |time_increment| x 2pi / |angle
/// increment|, else scan_time, else 0.
double messagePeriod(const PlanarScan& scan);

}  // namespace lidar_deskew::core
