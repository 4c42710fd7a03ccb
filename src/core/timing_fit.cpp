#include "lidar_deskew/core/timing_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>

namespace lidar_deskew::core {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr double kMovingTurn = 0.05;   // [rad/s] a scan below this turn rate and kMovingSpeed stands
constexpr double kMovingSpeed = 0.02;  // [m/s]

template <typename T>
T medianOf(std::vector<T> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

/// Scores of the pairs a measure scores (the coarse search's or all) at each offset of a grid, for one
/// beam order and period. Only pairs that the motion places at every offset of the grid count
/// (`scored`), so every offset is scored on the same pairs; a pair without overlap counts as the cap.
/// Only the pairs the measure scores are held: the coarse search's grid is long (+-max_search_range),
/// and its pairs are bounded (TimingFitConfig::coarse_pairs), so its memory does not grow with the
/// recording.
struct Curve {
  TimingConfig timing;                     // time_offset varies along the grid
  std::vector<double> offsets;             // [s]
  std::vector<std::size_t> members;        // [member] the pair's index in TimingFit::pairs()
  std::vector<std::vector<double>> pairs;  // [offset][member] distance [m], the cap where no overlap
  std::vector<char> scored;                // [member] placed at every offset
  std::size_t scored_pairs = 0;
  std::vector<double> mean;  // [offset] over the scored pairs
};

void finish(Curve& curve, double cap) {
  curve.scored_pairs = std::count(curve.scored.begin(), curve.scored.end(), 1);
  curve.mean.clear();
  for (const std::vector<double>& distances : curve.pairs) {
    double sum = 0.0;
    for (std::size_t m = 0; m < distances.size(); ++m)
      sum += curve.scored[m] ? distances[m] : 0.0;
    curve.mean.push_back(curve.scored_pairs ? sum / curve.scored_pairs : cap);
  }
}

/// One search's rows already scored (one fit, one beam order and period), by measure and offset: the
/// window widened round the same centre, or the window alone after the whole range, holds offsets
/// scored before, bit for bit (centre + k step), and a row depends on its offset alone.
class RowCache {
 public:
  struct Row {
    std::vector<double> distances;  // [member] as Curve::pairs
    std::vector<char> scored;       // [member] placed at this offset
  };
  /// The row of `offset` under the measure, or nullptr.
  const Row* find(bool coarse, double offset) const {
    const auto found = rows_.find(key(coarse, offset));
    return found == rows_.end() ? nullptr : &found->second;
  }
  /// Keeps `row` as the row of `offset` (not yet kept) and returns it.
  const Row& add(bool coarse, double offset, Row row) {
    return rows_.emplace(key(coarse, offset), std::move(row)).first->second;
  }

 private:
  // The offset's bits (-0.0 and 0.0 apart), and the measure.
  static std::pair<bool, std::uint64_t> key(bool coarse, double offset) {
    std::uint64_t bits;
    std::memcpy(&bits, &offset, sizeof bits);
    return {coarse, bits};
  }
  std::map<std::pair<bool, std::uint64_t>, Row> rows_;
};

Curve evaluate(const TimingFit& fit, const TimingConfig& timing, const std::vector<double>& offsets,
               bool coarse, double cap, RowCache& cache) {
  Curve curve;
  curve.timing = timing;
  curve.offsets = offsets;
  if (coarse) {
    curve.members = fit.coarsePairs();
  } else {
    curve.members.resize(fit.pairs().size());
    for (std::size_t p = 0; p < curve.members.size(); ++p)
      curve.members[p] = p;
  }
  curve.scored.assign(curve.members.size(), 1);
  std::vector<char> scored;
  std::vector<PlacedScan> placed;  // reused from offset to offset
  for (double offset : offsets) {
    const RowCache::Row* row = cache.find(coarse, offset);
    if (!row) {
      TimingConfig shifted = timing;
      shifted.time_offset = offset;
      const std::vector<double> distances = fit.pairDistances(shifted, scored, coarse, placed);
      RowCache::Row made;
      made.distances.resize(curve.members.size());
      made.scored.resize(curve.members.size());
      for (std::size_t m = 0; m < curve.members.size(); ++m) {
        const std::size_t p = curve.members[m];
        made.scored[m] = scored[p];
        made.distances[m] = std::isfinite(distances[p]) ? distances[p] : cap;
      }
      row = &cache.add(coarse, offset, std::move(made));
    }
    for (std::size_t m = 0; m < curve.members.size(); ++m)
      curve.scored[m] = curve.scored[m] && row->scored[m];
    curve.pairs.push_back(row->distances);
  }
  finish(curve, cap);
  return curve;
}

/// One curve of two of the same pairs, its offsets in order; a pair is scored where both score it.
Curve merge(const Curve& a, const Curve& b, double cap) {
  Curve curve;
  curve.timing = a.timing;
  curve.members = a.members;
  curve.scored.resize(a.scored.size());
  for (std::size_t m = 0; m < a.scored.size(); ++m)
    curve.scored[m] = a.scored[m] && b.scored[m];
  std::vector<std::pair<double, const std::vector<double>*>> rows;
  for (const Curve* part : {&a, &b}) {
    for (std::size_t k = 0; k < part->offsets.size(); ++k)
      rows.emplace_back(part->offsets[k], &part->pairs[k]);
  }
  std::sort(rows.begin(), rows.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  for (const auto& [offset, row] : rows) {
    curve.offsets.push_back(offset);
    curve.pairs.push_back(*row);
  }
  finish(curve, cap);
  return curve;
}

std::vector<double> grid(double center, double half_width, double step) {
  std::vector<double> values;
  const int steps = static_cast<int>(std::ceil(half_width / step - 1e-9));
  for (int k = -steps; k <= steps; ++k)
    values.push_back(center + k * step);
  return values;
}

/// The minimum of `values` over the evenly spaced `at`, refined by a parabola through its neighbours;
/// `index` gets the grid point nearest it.
std::pair<double, double> minimumOf(const std::vector<double>& at, const std::vector<double>& values,
                                    std::size_t* index = nullptr) {
  const std::size_t k = std::min_element(values.begin(), values.end()) - values.begin();
  if (index)
    *index = k;
  if (k == 0 || k + 1 == values.size())
    return {at[k], values[k]};
  const double before = values[k - 1], here = values[k], after = values[k + 1];
  const double curvature = before - 2.0 * here + after;
  if (!(curvature > 0.0))
    return {at[k], here};
  const double shift = std::clamp(0.5 * (before - after) / curvature, -0.5, 0.5);
  const double step = at[k + 1] - at[k];
  return {at[k] + shift * step, here - 0.125 * (before - after) * (before - after) / curvature};
}

/// Per-offset means of a curve's scored pairs, each pair weighted.
std::vector<double> weightedMeans(const Curve& curve, const std::vector<double>& weights) {
  std::vector<double> means;
  double total = 0.0;
  for (std::size_t m = 0; m < curve.members.size(); ++m)
    total += curve.scored[m] ? weights[curve.members[m]] : 0.0;
  for (const std::vector<double>& distances : curve.pairs) {
    double sum = 0.0;
    for (std::size_t m = 0; m < distances.size(); ++m)
      sum += curve.scored[m] ? weights[curve.members[m]] * distances[m] : 0.0;
    means.push_back(total > 0.0 ? sum / total : std::numeric_limits<double>::infinity());
  }
  return means;
}

/// One beam order and period: the offset searched coarsely over a window round `center` [s], widened
/// while its best lies on the edge, then finely round the best.
struct Candidate {
  TimingConfig timing;  // order and period; time_offset unused
  double period = 0.0;
  Curve coarse, fine;
  double range = 0.0;  // [s] the coarse window's half width
  bool on_edge = false;
  double depth = 0.0;                // the coarse curve's depthOf() over the whole range searched
  double offset = 0.0, value = 0.0;  // the fine minimum
  std::size_t index = 0;             // its nearest fine grid point
};

/// How far the curve's minimum lies below its median, as a share of the median: 0 for a flat curve.
double depthOf(const std::vector<double>& values) {
  if (values.empty())
    return 0.0;
  const double median = medianOf(values);
  const double lowest = *std::min_element(values.begin(), values.end());
  return median > 0.0 ? (median - lowest) / median : 0.0;
}

/// `whole` [s]: when above `range`, the coarse search also scores the rest of +-whole round `center`
/// and takes the minimum over all of it (a flat stretch near the stamp can hold a spurious minimum
/// while the valley lies further out); the curve kept is the window's alone when the minimum lies
/// inside it, off its edge (as a search of the window alone gives), else the whole one.
/// `cache`: the rows scored so far under `timing` on this fit (a search that falls back to the window
/// alone rescores none).
Candidate search(const TimingFit& fit, const TimingConfig& timing, double period, double center, double range,
                 double whole, const TimingFitConfig& config, RowCache& cache) {
  Candidate candidate;
  candidate.timing = timing;
  candidate.period = period;
  const double step = std::min(config.coarse_step, period / 2.0);
  const double cap = config.coarse_consistency.cap;
  candidate.range = range;
  double best = 0.0;
  if (whole > range) {
    const std::vector<double> inner_grid = grid(center, range, step);
    std::vector<double> outer_grid;
    for (double offset : grid(center, whole, step)) {
      if (offset < inner_grid.front() - 0.5 * step || offset > inner_grid.back() + 0.5 * step)
        outer_grid.push_back(offset);
    }
    Curve inner = evaluate(fit, timing, inner_grid, true, cap, cache);
    Curve all = merge(inner, evaluate(fit, timing, outer_grid, true, cap, cache), cap);
    if (4 * all.scored_pairs < inner.scored_pairs) {
      // A recording not much longer than the whole range: few pairs are placed at every offset of it,
      // and a minimum over those is no comparison. The window round the stamp alone, as before.
      return search(fit, timing, period, center, range, range, config, cache);
    }
    candidate.depth = depthOf(all.mean);
    std::size_t k = 0, k_inner = 0;
    best = minimumOf(all.offsets, all.mean, &k).first;
    const double inner_best = minimumOf(inner.offsets, inner.mean, &k_inner).first;
    const bool inside =
        all.offsets[k] > inner_grid.front() + 0.5 * step && all.offsets[k] < inner_grid.back() - 0.5 * step;
    if (inside && k_inner != 0 && k_inner + 1 != inner.offsets.size()) {
      candidate.coarse = std::move(inner);
      best = inner_best;
      candidate.on_edge = false;
    } else {
      candidate.coarse = std::move(all);
      candidate.range = whole;
      candidate.on_edge = k == 0 || k + 1 == candidate.coarse.offsets.size();
    }
  } else {
    for (;;) {
      candidate.coarse = evaluate(fit, timing, grid(center, candidate.range, step), true, cap, cache);
      std::size_t k = 0;
      best = minimumOf(candidate.coarse.offsets, candidate.coarse.mean, &k).first;
      candidate.on_edge = k == 0 || k + 1 == candidate.coarse.offsets.size();
      if (!candidate.on_edge || candidate.coarse.scored_pairs == 0 ||
          2.0 * candidate.range > config.max_search_range + 1e-9)
        break;
      candidate.range *= 2.0;
    }
    candidate.depth = depthOf(candidate.coarse.mean);
  }
  // The fine search round the coarse best; the two measures' minima may lie apart (the fine one caps
  // at a fifth of the coarse one's distance), so the window moves on while its best lies on its edge.
  const double fine_step = std::min(config.resolution * 5.0, step / 4.0);
  for (int moves = 0; moves < 8; ++moves) {
    candidate.fine = evaluate(fit, timing, grid(best, step, fine_step), false, config.consistency.cap, cache);
    std::tie(candidate.offset, candidate.value) =
        minimumOf(candidate.fine.offsets, candidate.fine.mean, &candidate.index);
    if (candidate.index != 0 && candidate.index + 1 != candidate.fine.offsets.size())
      break;
    best = candidate.offset;
  }
  return candidate;
}

/// Mean over the pairs both candidates score of `a`'s distances at its fine grid point `ia` minus
/// `b`'s at `ib`, each pair weighted: negative when `a` fits better. NaN when they share no pair.
double compare(const Candidate& a, std::size_t ia, const Candidate& b, std::size_t ib,
               const std::vector<double>& weights) {
  double sum = 0.0, total = 0.0;
  for (std::size_t p = 0; p < weights.size(); ++p) {  // fine curves hold every pair, in order
    if (a.fine.scored[p] && b.fine.scored[p]) {
      sum += weights[p] * (a.fine.pairs[ia][p] - b.fine.pairs[ib][p]);
      total += weights[p];
    }
  }
  return total > 0.0 ? sum / total : std::numeric_limits<double>::quiet_NaN();
}

std::string formatSeconds(double seconds) {
  std::ostringstream text;
  text.precision(4);
  text << seconds;
  return text.str();
}

}  // namespace

double turnRate(const MotionSource& motion, TimeNs begin, TimeNs end) {
  return std::remainder(motion.basePose(end).yaw() - motion.basePose(begin).yaw(), kTwoPi) /
         nsToSeconds(end - begin);
}

double messagePeriod(const PlanarScan& scan) {
  const double share = std::abs(static_cast<double>(scan.angle_increment)) / kTwoPi;
  if (scan.time_increment != 0.0f && share > 0.0)
    return std::abs(static_cast<double>(scan.time_increment)) / share;
  return scan.scan_time > 0.0f ? scan.scan_time : 0.0;
}

double stampPeriod(const std::vector<PlanarScan>& scans, double* sigma) {
  std::vector<double> intervals;
  for (std::size_t i = 1; i < scans.size(); ++i) {
    const double interval = nsToSeconds(scans[i].stamp - scans[i - 1].stamp);
    if (interval > 0.0)
      intervals.push_back(interval);
  }
  if (intervals.empty())
    return 0.0;
  // Dropped scans give multiples, late ones jitter: the mean of those near the median.
  const double median = medianOf(intervals);
  double sum = 0.0, squares = 0.0;
  std::size_t count = 0;
  for (double interval : intervals) {
    if (std::abs(interval / median - 1.0) <= 0.2) {
      sum += interval;
      squares += interval * interval;
      ++count;
    }
  }
  const double mean = sum / count;
  if (sigma)
    *sigma = count > 1 ? std::sqrt(std::max(0.0, squares / count - mean * mean) / (count - 1)) : 0.0;
  return mean;
}

TimingFit::TimingFit(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount,
                     const MotionSource& motion, double nominal_period, const TimingFitConfig& config)
    : mount_(mount), motion_(motion), nominal_period_(nominal_period), config_(config) {
  std::sort(scans.begin(), scans.end(),
            [](const PlanarScan& a, const PlanarScan& b) { return a.stamp < b.stamp; });
  if (nominal_period_ <= 0.0)
    nominal_period_ = stampPeriod(scans, &nominal_sigma_);
  if (!(nominal_period_ > 0.0) || !std::isfinite(nominal_period_))
    throw InvalidInput("period", "cannot be told: give it, or scans with increasing stamps");
  std::vector<double> message_periods;
  for (const PlanarScan& scan : scans)
    message_periods.push_back(core::messagePeriod(scan));
  message_period_ = message_periods.empty() ? 0.0 : medianOf(message_periods);
  all_scans_ = std::move(scans);
  shift(0.0);
}

void TimingFit::shift(double offset) {
  shift_ = offset;
  scans_.clear();
  motions_.clear();
  pairs_.clear();
  const TimeNs period = secondsToNs(nominal_period_);
  const TimeNs shift = secondsToNs(offset);
  std::vector<double> gaps;
  for (const PlanarScan& scan : all_scans_) {
    try {
      const TimeNs begin = scan.stamp + shift;
      const mrpt::poses::CPose3D start = motion_.basePose(begin);
      const mrpt::poses::CPose3D end = motion_.basePose(begin + period);
      ScanMotion moved;
      moved.turn_rate = std::remainder(end.yaw() - start.yaw(), kTwoPi) / nominal_period_;  // (poses at hand)
      moved.speed = std::hypot(end.x() - start.x(), end.y() - start.y()) / nominal_period_;
      motions_.push_back(moved);
      gaps.push_back(nsToSeconds(motion_.longestGap(begin, begin + period)));
      scans_.push_back(scan);
    } catch (const MotionUnavailable&) {
    }
  }
  if (scans_.empty())
    throw InvalidInput("scans", "motion covers none of them");
  odometry_interval_ = medianOf(gaps);
  // Pairs that overlap under the nominal period with the stamp at the first beam, at the last, or the
  // beams reversed (a timing that far off distorts fast turns by metres), among scans of which one moves.
  TimingConfig nominal;
  nominal.scan_period = nominal_period_;
  nominal.use_scan_period = true;
  nominal.time_offset = offset;
  TimingConfig at_end = nominal;
  at_end.stamp_at = StampAt::kEnd;
  TimingConfig reversed = nominal;
  reversed.beam_order = BeamOrder::kReversed;
  std::set<std::pair<std::size_t, std::size_t>> chosen;
  for (const TimingConfig& timing : {nominal, at_end, reversed}) {
    for (const auto& pair : overlappingPairs(place(timing), config_.pairs, config_.consistency))
      chosen.insert(pair);
  }
  const auto moving = [&](std::size_t i) {
    return std::abs(motions_[i].turn_rate) >= kMovingTurn || motions_[i].speed >= kMovingSpeed;
  };
  for (const auto& pair : chosen) {
    if (moving(pair.first) || moving(pair.second))
      pairs_.push_back(pair);
  }
  // The coarse search's pairs: at most coarse_pairs, spread evenly over the recording (pairs are in
  // the order of their earlier scan).
  coarse_pairs_.assign(pairs_.size(), 0);
  coarse_scans_.assign(scans_.size(), kLeftOut);
  const std::size_t coarse = std::min(config_.coarse_pairs, pairs_.size());
  for (std::size_t k = 0; k < coarse; ++k) {
    const std::size_t p = spreadIndex(k, coarse, pairs_.size());
    coarse_pairs_[p] = 1;
    if (coarse_scans_[pairs_[p].second] == kLeftOut)
      coarse_scans_[pairs_[p].second] = kPointsOnly;
  }
  for (std::size_t k = 0; k < coarse; ++k)
    coarse_scans_[pairs_[spreadIndex(k, coarse, pairs_.size())].first] = kPlaced;
  fine_scans_.assign(scans_.size(), kPointsOnly);
  for (const auto& pair : pairs_)
    fine_scans_[pair.first] = kPlaced;
}

std::size_t TimingFit::turningScans() const {
  return std::count_if(motions_.begin(), motions_.end(),
                       [&](const ScanMotion& m) { return std::abs(m.turn_rate) >= config_.turning_rate; });
}

bool TimingFit::placeOne(std::size_t i, const TimingConfig& timing, ScanDeskewer& deskewer,
                         DeskewedScan& corrected, PlacedScan& result, std::size_t stride,
                         bool indexed) const {
  const PlanarScan& scan = scans_[i];
  try {
    deskewer.deskew(scan, resolveTiming(scan, timing), mount_, motion_, corrected);
    placeCorrected(corrected, motion_.basePose(corrected.reference_time) + mount_,
                   std::abs(static_cast<double>(scan.angle_increment)), stride, result, indexed);
    return true;
  } catch (const InvalidInput&) {
  } catch (const MotionUnavailable&) {
  }
  result.clear();
  return false;
}

std::vector<PlacedScan> TimingFit::place(const TimingConfig& timing, std::vector<char>* placed_scans,
                                         bool coarse, const std::vector<char>* needed) const {
  std::vector<PlacedScan> placed;
  place(timing, placed, placed_scans, coarse, needed);
  return placed;
}

void TimingFit::place(const TimingConfig& timing, std::vector<PlacedScan>& placed,
                      std::vector<char>* placed_scans, bool coarse, const std::vector<char>* needed) const {
  DeskewConfig deskew;
  deskew.reference = Reference::kMiddle;
  if (coarse)
    deskew.interpolation = Interpolation::kLinear;
  ScanDeskewer deskewer(deskew);
  DeskewedScan corrected;
  placed.resize(scans_.size());
  if (placed_scans)
    placed_scans->assign(scans_.size(), 0);
  for (std::size_t i = 0; i < scans_.size(); ++i) {
    bool ok = false;
    if (needed && (*needed)[i] == kLeftOut) {
      placed[i].clear();
    } else {
      // The coarse search places at most about 360 returns a scan (every k-th): it only has to find the
      // valley.
      const std::size_t stride = coarse ? (scans_[i].ranges.size() + 359) / 360 : 1;
      ok = placeOne(i, timing, deskewer, corrected, placed[i], std::max<std::size_t>(1, stride),
                    !needed || (*needed)[i] != kPointsOnly);
    }
    if (placed_scans)
      (*placed_scans)[i] = ok;
  }
}

std::vector<PlacedScan> TimingFit::placeRaw() const {
  std::vector<PlacedScan> placed;
  placed.reserve(scans_.size());
  for (const PlanarScan& scan : scans_) {
    // The stamp itself may lie outside the motion when the scans were chosen under a shift (a scan at
    // the recording's edge): that scan is left out of the raw measure, like any the motion misses.
    try {
      placed.push_back(core::placeRaw(scan, motion_.basePose(scan.stamp) + mount_, scan.stamp));
    } catch (const MotionUnavailable&) {
      placed.emplace_back();
    }
  }
  return placed;
}

std::vector<double> TimingFit::pairDistances(const std::vector<PlacedScan>& placed) const {
  std::vector<double> distances;
  distances.reserve(pairs_.size());
  for (const auto& [earlier, later] : pairs_) {
    distances.push_back(placed[earlier].empty() || placed[later].empty()
                            ? std::numeric_limits<double>::quiet_NaN()
                            : pairDistance(placed[later], placed[earlier], config_.consistency));
  }
  return distances;
}

std::vector<double> TimingFit::pairDistances(const TimingConfig& timing) const {
  return pairDistances(place(timing));
}

std::vector<double> TimingFit::pairDistances(const TimingConfig& timing, std::vector<char>& scored,
                                             bool coarse, std::vector<PlacedScan>& placed) const {
  std::vector<char> placed_scans;
  place(timing, placed, &placed_scans, coarse, coarse ? &coarse_scans_ : &fine_scans_);
  const ConsistencyConfig& measure = coarse ? config_.coarse_consistency : config_.consistency;
  std::vector<double> distances(pairs_.size(), std::numeric_limits<double>::quiet_NaN());
  scored.assign(pairs_.size(), 0);
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    const auto [earlier, later] = pairs_[p];
    scored[p] = (!coarse || coarse_pairs_[p]) && placed_scans[earlier] && placed_scans[later];
    if (scored[p] && !placed[earlier].empty() && !placed[later].empty())
      distances[p] = pairDistance(placed[later], placed[earlier], measure);
  }
  return distances;
}

std::vector<std::size_t> TimingFit::coarsePairs() const {
  std::vector<std::size_t> indices;
  for (std::size_t p = 0; p < coarse_pairs_.size(); ++p) {
    if (coarse_pairs_[p])
      indices.push_back(p);
  }
  return indices;
}

std::string toString(TimingCause cause) {
  switch (cause) {
    case TimingCause::kNone:
      return "none";
    case TimingCause::kTooFewPairs:
      return "too few overlapping pairs";
    case TimingCause::kTooLittleTurning:
      return "too little turning";
    case TimingCause::kTurningTooUniform:
      return "turning too uniform";
    case TimingCause::kOdometryTooCoarse:
      return "odometry too coarse";
    case TimingCause::kNoClearMinimum:
      return "no clear minimum";
    case TimingCause::kWorseThanRaw:
      return "worse than raw";
    case TimingCause::kTooFlat:
      return "too flat";
    case TimingCause::kUndecided:
      return "order or period undecided";
  }
  return "?";
}

TimingEstimate estimateTiming(TimingFit& fit, const TimingFitConfig& config) {
  TimingEstimate estimate;
  estimate.turning_rate = config.turning_rate;
  estimate.message_period = fit.messagePeriod();
  const double nominal = fit.nominalPeriod();
  estimate.period = estimate.message_period > 0.0 ? estimate.message_period : nominal;
  estimate.time_offset = std::numeric_limits<double>::quiet_NaN();

  // What the motion can show: pairs with a turning scan (the beam order and the period bend turning
  // scans), and pairs whose scans turn at different rates (an offset shows only there).
  std::ostringstream counts;
  const auto count = [&] {
    estimate.scans = fit.scanCount();
    estimate.left_out = fit.leftOut();
    estimate.pairs = fit.pairs().size();
    estimate.turning_scans = fit.turningScans();
    estimate.odometry_interval = fit.odometryInterval();
    estimate.fastest_turn = 0.0;
    for (const ScanMotion& motion : fit.motions())
      estimate.fastest_turn = std::max(estimate.fastest_turn, std::abs(motion.turn_rate));
    estimate.turning_pairs = estimate.changing_pairs = 0;
    for (const auto& [earlier, later] : fit.pairs()) {
      const double a = fit.motions()[earlier].turn_rate, b = fit.motions()[later].turn_rate;
      if (std::max(std::abs(a), std::abs(b)) >= config.turning_rate)
        ++estimate.turning_pairs;
      if (std::abs(a - b) >= config.turning_rate)
        ++estimate.changing_pairs;
    }
    counts.str("");
    counts << estimate.turning_scans << " scans turn at " << config.turning_rate
           << " rad/s or faster (fastest " << formatSeconds(estimate.fastest_turn) << " rad/s), "
           << estimate.turning_pairs << " overlapping pairs with a turning scan, " << estimate.changing_pairs
           << " whose scans' turn rates differ by " << config.turning_rate << " rad/s or more";
    estimate.raw = summarize(fit.pairDistances(fit.placeRaw()));
    estimate.before = summarize(fit.pairDistances(TimingConfig()));
  };
  count();
  const auto refuse = [&](TimingCause cause, const std::string& why) {
    estimate.cause = cause;
    estimate.why = why;
    return estimate;
  };
  if (estimate.pairs < config.min_turning_pairs)
    return refuse(TimingCause::kTooFewPairs,
                  "too few overlapping pairs of scans to tell the timing: " + std::to_string(estimate.pairs) +
                      " (at least " + std::to_string(config.min_turning_pairs) +
                      "); drive in sight of the same walls, within 3 m and 10 s");
  const auto flatness = [&](double depth, double range) {
    std::ostringstream text;
    text << "the score's minimum over +-" << formatSeconds(range * 1e3) << " ms lies "
         << formatSeconds(depth * 100.0) << " % below its median (at least "
         << formatSeconds(config.min_curve_depth * 100.0) << " % needed)";
    return text.str();
  };
  if (estimate.turning_scans < config.min_turning_scans ||
      estimate.turning_pairs < config.min_turning_pairs) {
    // How flat the score is under the message's order and period, over the whole range: a recording
    // that does not turn leaves it flat, and that is what keeps the timing from showing.
    TimingConfig message;
    message.scan_period = estimate.period;
    message.use_scan_period = true;
    const double whole = std::max(config.max_search_range, config.search_periods * estimate.period);
    RowCache cache;
    const Candidate probe = search(fit, message, estimate.period, 0.0, whole, 0.0, config, cache);
    estimate.curve_depth = probe.depth;
    estimate.search_range = probe.range;
    std::ostringstream why;
    const bool flat = probe.depth < config.min_curve_depth;
    why << (flat ? "the score is too flat to tell the timing: " + flatness(probe.depth, probe.range) +
                       ", as too little turning leaves it: "
                 : std::string("too little turning to tell the timing: "))
        << counts.str() << "; at least " << config.min_turning_scans << " turning scans and "
        << config.min_turning_pairs
        << " such pairs are needed (turn at 0.5-2 rad/s for a few seconds, starting and stopping, in sight "
           "of the same walls)";
    return refuse(flat ? TimingCause::kTooFlat : TimingCause::kTooLittleTurning, why.str());
  }

  // Candidates: both beam orders under the message's period and, where it is 0 or disagrees with the
  // stamps by more than 5 %, the stamps' period.
  std::vector<double> periods;
  if (config.given_period > 0.0) {
    periods.push_back(config.given_period);  // the user's: no other candidate
  } else {
    if (estimate.message_period > 0.0)
      periods.push_back(estimate.message_period);
    if (estimate.message_period <= 0.0 || std::abs(estimate.message_period / nominal - 1.0) > 0.05)
      periods.push_back(nominal);
  }
  std::vector<BeamOrder> orders{BeamOrder::kAsMessage, BeamOrder::kReversed};
  if (config.given_order)
    orders = {*config.given_order};
  std::vector<Candidate> candidates;
  std::size_t best = 0;
  std::vector<double> ones;
  // The first search's window: +-max(search_range, search_periods periods) round the stamp. The second,
  // round the first's best, need only hold the resamples' minima: a quarter of that, at least 10 steps.
  bool second = false;
  const auto range = [&](double period) {
    const double first = std::max(config.search_range, config.search_periods * period);
    return second ? std::max(0.25 * first, 10.0 * std::min(config.coarse_step, period / 2.0)) : first;
  };
  const auto searchAll = [&] {
    candidates.clear();
    for (double period : periods) {
      for (BeamOrder order : orders) {
        TimingConfig timing;
        timing.beam_order = order;
        timing.scan_period = period;
        timing.use_scan_period = true;
        RowCache cache;
        candidates.push_back(search(fit, timing, period, fit.shifted(), range(period),
                                    second ? 0.0 : std::max(config.max_search_range, range(period)), config,
                                    cache));
      }
    }
    // A candidate that cannot place most scans (a sweep longer than the motion covers) is out.
    std::size_t most_scored = 0;
    for (const Candidate& candidate : candidates)
      most_scored = std::max(most_scored, candidate.fine.scored_pairs);
    candidates.erase(
        std::remove_if(candidates.begin(), candidates.end(),
                       [&](const Candidate& c) { return 2 * c.fine.scored_pairs < most_scored; }),
        candidates.end());
    if (most_scored == 0)
      candidates.clear();
    ones.assign(fit.pairs().size(), 1.0);
    best = 0;
    for (std::size_t c = 1; c < candidates.size(); ++c) {
      if (compare(candidates[c], candidates[c].index, candidates[best], candidates[best].index, ones) < 0.0)
        best = c;
    }
  };
  searchAll();
  estimate.search_range = candidates.empty() ? 0.0 : candidates[best].range;
  estimate.curve_depth = candidates.empty() ? 0.0 : candidates[best].depth;
  // Found an offset well away from the stamps (where one can show at all)? Then the scans and pairs are
  // chosen anew as if the stamps were that much later, and searched again: the same scans and pairs
  // whatever the stamps.
  if (!candidates.empty() && !candidates[best].on_edge &&
      estimate.changing_pairs >= config.min_changing_pairs &&
      std::abs(candidates[best].offset) > std::min(config.coarse_step, candidates[best].period / 2.0)) {
    fit.shift(candidates[best].offset);
    count();
    second = true;
    searchAll();
  }
  if (candidates.empty())
    return refuse(TimingCause::kTooFewPairs, "no pair of scans can be scored under any timing");
  const Candidate& chosen = candidates[best];
  // The best of the other beam order and of the other period, for their confidence.
  const auto bestOther = [&](auto differs) -> const Candidate* {
    const Candidate* other = nullptr;
    for (const Candidate& candidate : candidates) {
      if (differs(candidate) &&
          (!other || compare(candidate, candidate.index, *other, other->index, ones) < 0.0))
        other = &candidate;
    }
    return other;
  };
  const Candidate* order_rival =
      bestOther([&](const Candidate& c) { return c.timing.beam_order != chosen.timing.beam_order; });
  const Candidate* period_rival = bestOther([&](const Candidate& c) { return c.period != chosen.period; });

  // Bootstrap over blocks of consecutive scans (a turn's scans share its motion and odometry errors):
  // a resample draws blocks with replacement until it holds as many scans as the recording; a pair
  // counts as often as both its scans were drawn (the product: each scan's pose error enters every
  // pair it is in, earlier or later). Each resample's minimum is sought over the whole
  // coarse window, then, when it falls in the fine window, on the fine grid.
  const auto resampledMinimum = [](const Candidate& candidate, const std::vector<double>& weights,
                                   std::size_t& index) {
    const std::vector<double> coarse = weightedMeans(candidate.coarse, weights);
    const double at = minimumOf(candidate.coarse.offsets, coarse).first;
    const std::vector<double> fine = weightedMeans(candidate.fine, weights);
    const double found = minimumOf(candidate.fine.offsets, fine, &index).first;
    return at < candidate.fine.offsets.front() || at > candidate.fine.offsets.back() ? at : found;
  };
  const std::size_t n = fit.scanCount();
  const std::size_t block =
      std::clamp<std::size_t>(static_cast<std::size_t>(std::lround(config.block_duration / nominal)), 1, n);
  estimate.block_scans = block;
  std::mt19937 random(config.seed);
  std::uniform_int_distribution<std::size_t> draw(0, n - block);
  std::vector<double> offsets;
  std::size_t order_held = 0, period_held = 0;
  const auto& pairs = fit.pairs();
  for (std::size_t r = 0; r < std::max<std::size_t>(2, config.resamples); ++r) {
    std::vector<double> drawn(n, 0.0);
    for (std::size_t filled = 0; filled < n;) {
      const std::size_t start = draw(random);
      for (std::size_t k = start; k < start + block && filled < n; ++k, ++filled)
        drawn[k] += 1.0;
    }
    std::vector<double> weights(pairs.size());
    double total = 0.0;
    for (std::size_t p = 0; p < pairs.size(); ++p)
      total += weights[p] = drawn[pairs[p].first] * drawn[pairs[p].second];
    if (total <= 0.0)
      continue;  // no pair drawn: nothing to say
    std::size_t index = 0, rival_index = 0;
    offsets.push_back(resampledMinimum(chosen, weights, index));
    const auto holds = [&](const Candidate* rival) {
      if (!rival)
        return true;
      (void)resampledMinimum(*rival, weights, rival_index);
      return !(compare(chosen, index, *rival, rival_index, weights) > 0.0);
    };
    order_held += holds(order_rival);
    period_held += holds(period_rival);
  }
  if (offsets.size() < 2)
    return refuse(TimingCause::kTooFewPairs, "too few pairs to tell the timing");
  // The spread of the resamples' minima, and the fine grid's own resolution.
  const double fine_step =
      chosen.fine.offsets.size() > 1 ? chosen.fine.offsets[1] - chosen.fine.offsets[0] : 0.0;
  estimate.offset_sigma = std::hypot(summarize(offsets).spread, fine_step / std::sqrt(12.0));
  estimate.order_confidence = static_cast<double>(order_held) / offsets.size();
  estimate.period_confidence = static_cast<double>(period_held) / offsets.size();
  estimate.on_edge = chosen.on_edge;
  estimate.period = chosen.period;
  estimate.period_estimated = chosen.period != estimate.message_period;
  estimate.period_given = config.given_period > 0.0;
  estimate.period_sigma =
      estimate.period_estimated && !estimate.period_given ? fit.nominalPeriodSigma() : 0.0;
  for (std::size_t k = 0; k < chosen.coarse.offsets.size(); ++k)
    estimate.coarse_curve.emplace_back(chosen.coarse.offsets[k], chosen.coarse.mean[k]);
  for (std::size_t k = 0; k < chosen.fine.offsets.size(); ++k)
    estimate.fine_curve.emplace_back(chosen.fine.offsets[k], chosen.fine.mean[k]);

  if (estimate.order_confidence < config.min_confidence ||
      estimate.period_confidence < config.min_confidence) {
    // The recording turned enough (checked above): what is undecided is the order or the period
    // itself, and the user who knows it can give it.
    std::ostringstream why;
    const bool period_open = estimate.period_confidence < config.min_confidence;
    const bool order_open = estimate.order_confidence < config.min_confidence;
    why << "undecided: ";
    if (period_open) {
      why << "the period: the stamps say one scan every " << formatSeconds(nominal * 1e3) << " ms (+- "
          << formatSeconds(fit.nominalPeriodSigma() * 1e3) << " ms), the message "
          << (estimate.message_period > 0.0 ? formatSeconds(estimate.message_period * 1e3) + " ms"
                                            : std::string("nothing"))
          << "; " << formatSeconds(chosen.period * 1e3) << " ms held in "
          << formatSeconds(estimate.period_confidence * 100.0) << " % of resamples";
    }
    if (order_open) {
      why << (period_open ? "; " : "") << "the beam order: "
          << (chosen.timing.beam_order == BeamOrder::kReversed ? "reversed" : "as the message says")
          << " held in " << formatSeconds(estimate.order_confidence * 100.0) << " % of resamples";
    }
    why << " (at least " << formatSeconds(config.min_confidence * 100.0)
        << " % needed), although the recording turns enough (" << counts.str() << ")";
    if (period_open)
      why << ". If you know the period, give it: deskew_calibrate --scan-period S (the node's scan_period "
             "with use_scan_period: true)";
    if (order_open)
      why << ". If you know the beam order, give it: deskew_calibrate --beam-order as_message|reversed "
             "(the node's beam_order)";
    why << "; odometry that disagrees with the scans' turn, or a wrong mount, also blurs them";
    return refuse(TimingCause::kUndecided, why.str());
  }

  // The offset: told when its minimum lies inside the window, its uncertainty is small against the
  // period, and scans that turn at different rates overlap (under one constant twist a constant offset
  // moves every scan by the same rigid transform of the world, which no comparison of scans can see).
  std::ostringstream offset_why;
  TimingCause offset_cause = TimingCause::kNone;
  const std::string seen = "the best offset " + formatSeconds(chosen.offset * 1e3) + " ms +- " +
                           formatSeconds(estimate.offset_sigma * 1e3) + " ms";
  if (estimate.changing_pairs < config.min_changing_pairs) {
    offset_cause = TimingCause::kTurningTooUniform;
    offset_why << "the motion was too uniform to see an offset: overlapping scans turn alike ("
               << counts.str() << "; at least " << config.min_changing_pairs
               << " are needed). Under a constant twist a constant offset moves every scan by the same rigid "
                  "transform, which no comparison of scans can see; turn, starting and stopping, to see it";
  } else if (estimate.curve_depth < config.min_curve_depth) {
    offset_cause = TimingCause::kTooFlat;
    offset_why << "the score is too flat to tell the offset: "
               << flatness(estimate.curve_depth, estimate.search_range) << "; " << seen;
  } else if (chosen.on_edge) {
    offset_cause = TimingCause::kNoClearMinimum;
    offset_why << "no offset within +-" << formatSeconds(chosen.range * 1e3)
               << " ms fits: the best lies on the search window's edge ("
               << formatSeconds(chosen.offset * 1e3) << " ms), which is no estimate";
  } else if (estimate.offset_sigma > config.max_uncertainty_share * estimate.period) {
    // The odometry is blamed only where its samples lie half a sweep or more apart and it is slower
    // than the rate the advice names: a 40 Hz scanner with 50 Hz odometry is not held back by it.
    const bool coarse_odometry = estimate.odometry_interval >= 0.5 * estimate.period &&
                                 estimate.odometry_interval > config.fine_odometry_interval;
    offset_cause = coarse_odometry ? TimingCause::kOdometryTooCoarse : TimingCause::kNoClearMinimum;
    offset_why << "the offset is too uncertain to write: " << seen << " (at most "
               << formatSeconds(config.max_uncertainty_share * estimate.period * 1e3) << " ms, "
               << formatSeconds(config.max_uncertainty_share * 100.0) << " % of the period)";
    if (coarse_odometry)
      offset_why << "; the odometry is too coarse: its samples lie "
                 << formatSeconds(estimate.odometry_interval * 1e3)
                 << " ms apart (median over the sweeps), against a " << formatSeconds(estimate.period * 1e3)
                 << " ms sweep; record odometry at 50 Hz or more";
    else
      offset_why << "; " << flatness(estimate.curve_depth, estimate.search_range) << ", with odometry every "
                 << formatSeconds(estimate.odometry_interval * 1e3) << " ms and " << counts.str()
                 << ": the scans' agreement changes little with the offset (odometry noise, a wrong mount, "
                    "moving objects)";
  }
  estimate.offset_told = offset_cause == TimingCause::kNone;
  estimate.time_offset = chosen.offset;

  // As parameters: the offset snapped to "as the message says" or to "stamped at the end" when that
  // close; where it is not told, the message's.
  TimingConfig& timing = estimate.timing;
  timing.beam_order = chosen.timing.beam_order;
  if (estimate.period_estimated) {
    timing.scan_period = estimate.period;
    timing.use_scan_period = estimate.message_period > 0.0;
  }
  const PlanarScan& first = fit.scan(0);
  const double sweep = estimate.sweep =
      estimate.period * std::abs(static_cast<double>(first.angle_increment)) / kTwoPi *
      static_cast<double>(first.ranges.empty() ? 0 : first.ranges.size() - 1);
  const double tolerance = std::max(config.snap, 2.0 * estimate.offset_sigma);
  if (!estimate.offset_told || std::abs(chosen.offset) <= tolerance) {
    timing.time_offset = 0.0;
  } else if (std::abs(chosen.offset + sweep) <= tolerance) {
    timing.stamp_at = StampAt::kEnd;
    timing.time_offset = 0.0;
  } else {
    timing.time_offset = std::round(chosen.offset * 1e5) / 1e5;  // 10 us
  }
  estimate.after = summarize(fit.pairDistances(timing));
  // A timing under which corrected scans agree less than raw ones is no timing to write: the odometry
  // or the mount is off, and no timing helps.
  if (estimate.after.pairs > 0 && estimate.raw.pairs > 0 && estimate.after.mean > estimate.raw.mean) {
    std::ostringstream why;
    why << "corrected with the best timing found, overlapping scans agree less than raw ones ("
        << formatSeconds(estimate.after.mean * 1e3) << " mm against "
        << formatSeconds(estimate.raw.mean * 1e3) << " mm): the odometry"
        << (estimate.odometry_interval >= 0.5 * estimate.period
                ? " (samples " + formatSeconds(estimate.odometry_interval * 1e3) + " ms apart)"
                : std::string())
        << " or the laser's mount does not fit the scans; nothing to write";
    estimate.offset_told = false;
    return refuse(TimingCause::kWorseThanRaw, why.str());
  }
  estimate.told = true;
  estimate.cause = offset_cause;
  estimate.why = offset_why.str();
  estimate.changed = timing.beam_order != BeamOrder::kAsMessage || timing.stamp_at != StampAt::kStart ||
                     timing.time_offset != 0.0 || estimate.period_estimated;
  return estimate;
}

TimingCheck::TimingCheck(const TimingConfig& configured, const TimingCheckConfig& config)
    : config_(config), deskewer_([] {
        DeskewConfig deskew;
        // The alternatives differ by whole stamps and orders: tf's own straight line tells them apart
        // as well, at a fraction of the twist fit's cost (each alternative's span starts elsewhere, so
        // the fit's cache of tf answers would start over for each), and the check has a CPU budget.
        deskew.interpolation = Interpolation::kLinear;
        deskew.reference = Reference::kMiddle;
        deskew.knot_interval = 0.02;  // plus tf's own samples: a few lookups per sweep
        return deskew;
      }()) {
  reset(configured);
}

void TimingCheck::reset(const TimingConfig& configured) {
  configured_ = configured;
  history_.clear();
  sums_.assign(5, 0.0);
  wins_.assign(5, 0);
  pairs_ = 0;
  scans_ = 0;
  timings_.clear();
  pending_.clear();
  offered_.clear();
  shape_pairs_.clear();
}

void TimingCheck::offer(const PlanarScan& scan) {
  const TimeNs keep = secondsToNs(config_.shape.max_interval + 1.0);  // + 1 s: a checked scan may wait
  while (!offered_.empty() &&
         (offered_.size() >= config_.offered || scan.stamp - offered_.front().stamp > keep ||
          offered_.front().stamp > scan.stamp))  // time went back: start over
    offered_.pop_front();
  offered_.push_back(scan);
}

bool TimingCheck::add(const PlanarScan& scan, const mrpt::poses::CPose3D& mount, const MotionSource& motion) {
  // Scans wait here, in order, until the motion covers every alternative (with stamp_at end configured,
  // the "start" one reaches a sweep past the last beam, which tf brings later). A new scan may come with
  // the very tf that completes the one before it: it queues behind it, and the oldest of more than
  // three is dropped.
  pending_.push_back(Pending{scan, mount});
  if (pending_.size() > 3)
    pending_.pop_front();
  return tryPending(motion);
}

bool TimingCheck::tryPending(const MotionSource& motion) {
  if (pending_.empty())
    return false;
  const PlanarScan& scan = pending_.front().scan;
  const mrpt::poses::CPose3D& mount = pending_.front().mount;
  // The configured timing and its alternatives for this scan.
  std::vector<std::pair<std::string, TimingConfig>> timings;
  Entry entry;
  entry.time = scan.stamp;
  TimeNs begin = std::numeric_limits<TimeNs>::min();  // [ns] the configured sweep's first beam
  TimeNs sweep_middle = 0;                            // [ns] ... and its middle
  std::size_t stride = 1;
  try {
    const BeamTiming beams = resolveTiming(scan, configured_);
    begin = beams.earliestBeamTime();
    const TimeNs end = std::max(beams.latestBeamTime(), begin + 1);
    const double sweep = nsToSeconds(end - begin);
    const auto flipStamp = [](TimingConfig timing) {
      timing.stamp_at = timing.stamp_at == StampAt::kStart ? StampAt::kEnd : StampAt::kStart;
      return timing;
    };
    const auto flipOrder = [](TimingConfig timing) {
      timing.beam_order =
          timing.beam_order == BeamOrder::kAsMessage ? BeamOrder::kReversed : BeamOrder::kAsMessage;
      return timing;
    };
    TimingConfig middle = configured_;
    middle.time_offset += configured_.stamp_at == StampAt::kStart ? -0.5 * sweep : 0.5 * sweep;
    const std::string stamp_name = "stamp_at: " + toString(flipStamp(configured_).stamp_at);
    const std::string order_name = "beam_order: " + toString(flipOrder(configured_).beam_order);
    char offset_name[64];
    std::snprintf(offset_name, sizeof offset_name, "time_offset: %.4f (the stamp mid-sweep)",
                  middle.time_offset);
    timings = {{"the configured timing", configured_},
               {stamp_name, flipStamp(configured_)},
               {order_name, flipOrder(configured_)},
               {stamp_name + ", " + order_name, flipOrder(flipStamp(configured_))},
               {offset_name, middle}};
    // Covered under every timing? (One lookup at each end, before any correction.)
    std::vector<BeamTiming> resolved;
    for (const auto& named : timings) {
      resolved.push_back(resolveTiming(scan, named.second));
      (void)motion.basePose(resolved.back().earliestBeamTime());
      (void)motion.basePose(resolved.back().latestBeamTime());
    }
    entry.turn_rate = turnRate(motion, begin, end);
    // Every return corrected, every k-th placed: at most config_.beams a scan.
    stride = strideFor(scan);
    sweep_middle = begin + (end - begin) / 2;
    for (const BeamTiming& beams_of_timing : resolved) {
      deskewer_.deskew(scan, beams_of_timing, mount, motion, corrected_);
      entry.placed.push_back(placeCorrected(corrected_, motion.basePose(corrected_.reference_time) + mount,
                                            std::abs(static_cast<double>(scan.angle_increment)), stride));
    }
  } catch (const MotionUnavailable& error) {
    // Not yet covered: it waits for later tf, unless tf will never cover it, and then it is left out:
    // - a time at or before the configured sweep's start is missing (tf covered that sweep when the scan
    //   was corrected, so it has dropped it since: tf keeps a limited past, and a scan that waited
    //   while the check's budget let no attempt through would otherwise block the check for good);
    // - a newer scan waits behind it already.
    if (error.time() <= begin ||
        (pending_.size() > 1 && pending_.back().scan.stamp - scan.stamp > secondsToNs(1.0)))
      pending_.pop_front();
    return false;
  } catch (const InvalidInput&) {
    pending_.pop_front();
    return false;
  }
  timings_ = std::move(timings);
  ++scans_;
  addShapePair(scan, mount, entry, sweep_middle, stride, motion);
  pending_.pop_front();  // (scan and mount refer to it)
  // Partners: spread over the history, the newest first.
  const TimeNs horizon = entry.time - secondsToNs(config_.history);
  history_.erase(
      std::remove_if(history_.begin(), history_.end(),
                     [&](const Entry& old) { return old.time < horizon || old.time >= entry.time; }),
      history_.end());
  const std::size_t count = std::min(config_.partners, history_.size());
  for (std::size_t k = 0; k < count; ++k) {
    const Entry& partner = history_[history_.size() - 1 - spreadIndex(k, count, history_.size())];
    if (std::max(std::abs(partner.turn_rate), std::abs(entry.turn_rate)) < config_.turning_rate)
      continue;
    // The pair counts when it overlaps under any of the timings (a wrong one distorts turns by metres).
    std::vector<double> distances(timings_.size());
    bool overlapping = false;
    for (std::size_t t = 0; t < timings_.size(); ++t) {
      double overlap = 0.0;
      distances[t] = pairDistance(entry.placed[t], partner.placed[t], config_.consistency, &overlap);
      overlapping = overlapping || overlap >= config_.consistency.min_overlap;
      if (!std::isfinite(distances[t]))
        distances[t] = config_.consistency.cap;
    }
    if (!overlapping)
      continue;
    for (std::size_t t = 0; t < timings_.size(); ++t) {
      sums_[t] += distances[t];
      if (t > 0 && distances[t] < distances[0])
        ++wins_[t];
    }
    ++pairs_;
  }
  history_.push_back(std::move(entry));
  return true;
}

void TimingCheck::addShapePair(const PlanarScan& scan, const mrpt::poses::CPose3D& mount, const Entry& entry,
                               TimeNs middle, std::size_t stride, const MotionSource& motion) {
  const ShapeConfig& shape = config_.shape;
  // The nearest earlier scan whose turn differs: tf's turn rates only choose the pair (and tf's relative
  // pose seeds the raw match); what is measured is the free match's aligned distance.
  const PlanarScan* partner = nullptr;
  TimeNs partner_middle = 0;
  for (auto it = offered_.rbegin(); it != offered_.rend() && !partner; ++it) {
    if (it->stamp >= scan.stamp)
      continue;
    if (scan.stamp - it->stamp > secondsToNs(shape.max_interval))
      break;
    try {
      const BeamTiming beams = resolveTiming(*it, configured_);
      const TimeNs begin = beams.earliestBeamTime();
      const TimeNs end = std::max(beams.latestBeamTime(), begin + 1);
      if (std::abs(turnRate(motion, begin, end) - entry.turn_rate) >= shape.min_turn_difference) {
        partner = &*it;
        partner_middle = begin + (end - begin) / 2;
      }
    } catch (const MotionUnavailable&) {
      return;  // tf no longer reaches back this far
    } catch (const InvalidInput&) {
    }
  }
  if (!partner)
    return;
  // Both scans in the fixed frame where tf puts them: raw (every beam at its stamp, drawn from the laser
  // at the sweep's middle) and under every timing, as many returns as the check keeps.
  const std::size_t partner_stride = strideFor(*partner);
  std::vector<PlacedScan> placed;  // the partner's, per timing
  PlacedScan partner_raw, raw;
  mrpt::poses::CPose3D partner_laser, laser;
  try {
    for (const auto& named : timings_) {
      deskewer_.deskew(*partner, resolveTiming(*partner, named.second), mount, motion, corrected_);
      placed.push_back(placeCorrected(corrected_, motion.basePose(corrected_.reference_time) + mount,
                                      std::abs(static_cast<double>(partner->angle_increment)),
                                      partner_stride));
    }
    partner_laser = motion.basePose(partner_middle) + mount;
    laser = motion.basePose(middle) + mount;
    partner_raw = placeRaw(*partner, partner_laser, partner_middle, partner_stride);
    raw = placeRaw(scan, laser, middle, stride);
  } catch (const MotionUnavailable&) {
    return;
  } catch (const InvalidInput&) {
    return;
  }
  const auto aligned = [&](const ScanMatch& match) {
    return match.valid && match.overlap >= shape.min_overlap && std::isfinite(match.distance);
  };
  ScanMatch raw_match = matchScans(partner_raw, raw.points(), Pose2d(), shape.match);
  if (!aligned(raw_match)) {
    // tf's rotation between the two may be what is wrong (by more than the coarse search): seed with the
    // laser not turning between them instead, about its own position.
    const double turn = partner_laser.yaw() - laser.yaw();
    const Pose2d rotate{0.0, 0.0, turn};
    const Eigen::Vector2d moved = rotate.apply({laser.x(), laser.y()});
    raw_match = matchScans(partner_raw, raw.points(),
                           Pose2d{laser.x() - moved.x(), laser.y() - moved.y(), turn}, shape.match);
    if (!aligned(raw_match))
      return;
  }
  // Each timing's scans from where the raw ones aligned: they differ by the distortion only.
  ScanMatchConfig refine = shape.match;
  refine.rotation_search = config_.refine_search;
  refine.iterations = config_.refine_iterations;
  std::vector<double> distances{raw_match.distance};
  const double cap = shape.match.score.cap;
  for (std::size_t t = 0; t < timings_.size(); ++t) {
    const ScanMatch match = matchScans(placed[t], entry.placed[t].points(), raw_match.pose, refine);
    // A timing under which the two do not even align counts the cap. One that aligns is scored over at
    // least as many of the checked scan's points as raw aligned: the points it lost count the cap (a
    // partner corrected out of shape that still overlaps half of the scan aligns that half closely).
    const double lost = std::max(0.0, raw_match.overlap - match.overlap);
    distances.push_back(aligned(match) ? (match.overlap * match.distance + lost * cap) /
                                             std::max(match.overlap, raw_match.overlap)
                                       : cap);
  }
  shape_pairs_.push_back(std::move(distances));
  if (shape_pairs_.size() > config_.shape_history)
    shape_pairs_.pop_front();
}

std::size_t TimingCheck::strideFor(const PlanarScan& scan) const {
  return std::max<std::size_t>(
      1, (scan.ranges.size() + config_.beams - 1) / std::max<std::size_t>(1, config_.beams));
}

TimingCheck::Verdict TimingCheck::verdict() const {
  Verdict verdict;
  verdict.pairs = pairs_;
  if (timings_.empty())
    return verdict;
  char text[400];
  // The shape score: per column (raw, then per timing) the median aligned distance over the pairs kept.
  verdict.shape_pairs = shape_pairs_.size();
  bool raw_beats_configured = false;
  if (!shape_pairs_.empty()) {
    const std::size_t columns = std::min(shape_pairs_.front().size(), timings_.size() + 1);
    std::vector<double> medians(columns);
    std::vector<double> column;
    for (std::size_t c = 0; c < columns; ++c) {
      column.clear();
      for (const std::vector<double>& pair : shape_pairs_)
        column.push_back(pair[c]);
      std::nth_element(column.begin(), column.begin() + column.size() / 2, column.end());
      medians[c] = column[column.size() / 2];
    }
    std::size_t best = 2;
    for (std::size_t c = 3; c < columns; ++c) {
      if (medians[c] < medians[best])
        best = c;
    }
    verdict.shape_raw = medians[0];
    verdict.shape_configured = medians[1];
    verdict.shape_best = medians[best];
    verdict.shape_best_name = timings_[best - 1].first;
    const std::size_t raw_wins = static_cast<std::size_t>(
        std::count_if(shape_pairs_.begin(), shape_pairs_.end(),
                      [](const std::vector<double>& pair) { return pair[0] < pair[1]; }));
    raw_beats_configured = verdict.shape_pairs >= config_.min_shape_pairs &&
                           verdict.shape_raw < config_.margin * verdict.shape_configured &&
                           raw_wins >= config_.min_win_share * static_cast<double>(verdict.shape_pairs);
  }
  const double shape_ratio = verdict.shape_configured / verdict.shape_raw;
  // No correction aligns markedly better than the configured timing, and at least as well as every
  // alternative: tf's motion (or a timing the check does not try) is wrong. Odometry between the scans
  // does not enter, so this holds also where the odometry-placed consistency below sees no overlap.
  if (raw_beats_configured && verdict.shape_raw <= verdict.shape_best) {
    verdict.state = State::kWorseThanRaw;
    std::snprintf(
        text, sizeof text,
        "correction makes shapes worse than raw: aligned distance %.2fx raw (%zu pairs while turning; "
        "best alternative, %s: %.2fx); tf's motion or the timing does not fit the scans. The node "
        "keeps correcting: check tf's odometry and the timing (deskew_calibrate)",
        shape_ratio, verdict.shape_pairs, verdict.shape_best_name.c_str(),
        verdict.shape_best / verdict.shape_raw);
    verdict.message = text;
    return verdict;
  }
  const bool consistency_known = pairs_ >= config_.min_pairs;
  if (consistency_known) {
    std::size_t best = 1;
    for (std::size_t t = 2; t < sums_.size(); ++t) {
      if (sums_[t] < sums_[best])
        best = t;
    }
    verdict.configured = sums_[0] / pairs_;
    verdict.best = sums_[best] / pairs_;
    verdict.best_name = timings_[best].first;
    if (verdict.best < config_.margin * verdict.configured &&
        wins_[best] >= config_.min_win_share * static_cast<double>(pairs_)) {
      verdict.state = State::kBetter;
      std::snprintf(text, sizeof text,
                    "timing fits markedly better with %s: overlapping scans %.1f mm apart against %.1f mm as "
                    "configured (%zu pairs while turning); check with deskew_calibrate",
                    verdict.best_name.c_str(), verdict.best * 1e3, verdict.configured * 1e3, pairs_);
      verdict.message = text;
      return verdict;
    }
  }
  // Raw beats the configured timing, and an alternative beats raw.
  if (raw_beats_configured && verdict.shape_best < verdict.shape_raw) {
    verdict.state = State::kBetter;
    verdict.best_name = verdict.shape_best_name;
    std::snprintf(text, sizeof text,
                  "timing fits markedly better with %s: scans aligned %.1f mm apart against %.1f mm as "
                  "configured and %.1f mm raw (%zu pairs while turning); check with deskew_calibrate",
                  verdict.shape_best_name.c_str(), verdict.shape_best * 1e3, verdict.shape_configured * 1e3,
                  verdict.shape_raw * 1e3, verdict.shape_pairs);
    verdict.message = text;
    return verdict;
  }
  if (!consistency_known)
    return verdict;
  verdict.state = State::kFits;
  std::snprintf(text, sizeof text,
                "timing fits: overlapping scans %.1f mm apart (best alternative, %s: %.1f mm; %zu pairs "
                "while turning)",
                verdict.configured * 1e3, verdict.best_name.c_str(), verdict.best * 1e3, pairs_);
  verdict.message = text;
  if (verdict.shape_pairs >= config_.min_shape_pairs) {
    std::snprintf(text, sizeof text, "; shapes aligned %.2fx raw (%zu pairs)", shape_ratio,
                  verdict.shape_pairs);
    verdict.message += text;
  }
  return verdict;
}

}  // namespace lidar_deskew::core
