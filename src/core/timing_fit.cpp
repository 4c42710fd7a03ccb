#include "lidar_deskew/core/timing_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
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

/// Scores of every pair at each offset of a grid, for one beam order and period.
struct Curve {
  TimingConfig timing;                     // time_offset varies along the grid
  std::vector<double> offsets;             // [s]
  std::vector<std::vector<double>> pairs;  // [offset][pair] distance [m], NaN as the cap
  std::vector<double> mean;                // [offset]
};

Curve evaluate(const TimingFit& fit, const TimingConfig& timing, const std::vector<double>& offsets,
               double cap) {
  Curve curve;
  curve.timing = timing;
  curve.offsets = offsets;
  for (double offset : offsets) {
    TimingConfig shifted = timing;
    shifted.time_offset = offset;
    std::vector<double> distances = fit.pairDistances(shifted);
    double sum = 0.0;
    for (double& distance : distances) {
      if (!std::isfinite(distance))
        distance = cap;
      sum += distance;
    }
    curve.mean.push_back(distances.empty() ? cap : sum / distances.size());
    curve.pairs.push_back(std::move(distances));
  }
  return curve;
}

std::vector<double> grid(double center, double half_width, double step) {
  std::vector<double> values;
  const int steps = static_cast<int>(std::ceil(half_width / step - 1e-9));
  for (int k = -steps; k <= steps; ++k)
    values.push_back(center + k * step);
  return values;
}

/// The minimum of `values` over the evenly spaced `at`, refined by a parabola through its neighbours.
std::pair<double, double> minimumOf(const std::vector<double>& at, const std::vector<double>& values) {
  const std::size_t k = std::min_element(values.begin(), values.end()) - values.begin();
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

/// Per-offset means of a curve with each pair weighted.
std::vector<double> weightedMeans(const Curve& curve, const std::vector<double>& weights) {
  std::vector<double> means;
  double total = 0.0;
  for (double weight : weights)
    total += weight;
  for (const std::vector<double>& distances : curve.pairs) {
    double sum = 0.0;
    for (std::size_t p = 0; p < distances.size(); ++p)
      sum += weights[p] * distances[p];
    means.push_back(total > 0.0 ? sum / total : 0.0);
  }
  return means;
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
  const TimeNs period = secondsToNs(nominal_period_);
  const TimeNs margin = secondsToNs(std::max(1.25 * nominal_period_, config.min_range) + 0.01);
  for (PlanarScan& scan : scans) {
    // Any offset searched and a sweep after it must be covered.
    try {
      (void)motion.basePose(scan.stamp - margin);
      const mrpt::poses::CPose3D start = motion.basePose(scan.stamp);
      const mrpt::poses::CPose3D end = motion.basePose(scan.stamp + period);
      (void)motion.basePose(scan.stamp + margin + period);
      ScanMotion moved;
      moved.turn_rate = std::remainder(end.yaw() - start.yaw(), kTwoPi) / nominal_period_;  // (poses at hand)
      moved.speed = std::hypot(end.x() - start.x(), end.y() - start.y()) / nominal_period_;
      motions_.push_back(moved);
      scans_.push_back(std::move(scan));
    } catch (const MotionUnavailable&) {
    }
  }
  if (scans_.empty())
    throw InvalidInput("scans", "motion covers none of them with a period to spare either side");
  // Pairs that overlap under the nominal period with the stamp at the first beam, at the last, or the
  // beams reversed (a timing that far off distorts fast turns by metres), among scans of which one moves.
  TimingConfig nominal;
  nominal.scan_period = nominal_period_;
  nominal.use_scan_period = true;
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
}

std::size_t TimingFit::turningScans() const {
  return std::count_if(motions_.begin(), motions_.end(),
                       [&](const ScanMotion& m) { return std::abs(m.turn_rate) >= config_.turning_rate; });
}

PlacedScan TimingFit::placeOne(std::size_t i, const TimingConfig& timing, ScanDeskewer& deskewer,
                               DeskewedScan& corrected) const {
  const PlanarScan& scan = scans_[i];
  try {
    deskewer.deskew(scan, resolveTiming(scan, timing), mount_, motion_, corrected);
    return placeCorrected(corrected, motion_.basePose(corrected.reference_time) + mount_,
                          std::abs(static_cast<double>(scan.angle_increment)));
  } catch (const InvalidInput&) {
  } catch (const MotionUnavailable&) {
  }
  return {};
}

std::vector<PlacedScan> TimingFit::place(const TimingConfig& timing) const {
  DeskewConfig deskew;
  deskew.reference = Reference::kMiddle;
  ScanDeskewer deskewer(deskew);
  DeskewedScan corrected;
  std::vector<PlacedScan> placed;
  placed.reserve(scans_.size());
  for (std::size_t i = 0; i < scans_.size(); ++i)
    placed.push_back(placeOne(i, timing, deskewer, corrected));
  return placed;
}

std::vector<PlacedScan> TimingFit::placeRaw() const {
  std::vector<PlacedScan> placed;
  for (const PlanarScan& scan : scans_)
    placed.push_back(core::placeRaw(scan, motion_.basePose(scan.stamp) + mount_, scan.stamp));
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

double TimingFit::score(const TimingConfig& timing) const {
  double sum = 0.0;
  const std::vector<double> distances = pairDistances(timing);
  for (double distance : distances)
    sum += std::isfinite(distance) ? distance : config_.consistency.cap;
  return distances.empty() ? config_.consistency.cap : sum / distances.size();
}

TimingEstimate estimateTiming(const TimingFit& fit, const TimingFitConfig& config) {
  TimingEstimate estimate;
  estimate.scans = fit.scanCount();
  estimate.pairs = fit.pairs().size();
  estimate.turning_scans = fit.turningScans();
  for (const ScanMotion& motion : fit.motions())
    estimate.fastest_turn = std::max(estimate.fastest_turn, std::abs(motion.turn_rate));
  const double cap = config.consistency.cap;
  estimate.raw = summarize(fit.pairDistances(fit.placeRaw()));
  estimate.before = summarize(fit.pairDistances(TimingConfig()));

  // The message's own period and the stamps'.
  estimate.message_period = fit.messagePeriod();
  const double nominal = fit.nominalPeriod();
  std::vector<double> periods;
  if (estimate.message_period > 0.0)
    periods.push_back(estimate.message_period);
  if (estimate.message_period <= 0.0 || std::abs(estimate.message_period / nominal - 1.0) > 0.05)
    periods.push_back(nominal);

  // Pairs that can tell: one of the two scans turns.
  std::size_t turning_pairs = 0;
  for (const auto& [earlier, later] : fit.pairs()) {
    if (std::max(std::abs(fit.motions()[earlier].turn_rate), std::abs(fit.motions()[later].turn_rate)) >=
        config.turning_rate)
      ++turning_pairs;
  }
  estimate.turning_pairs = turning_pairs;
  if (estimate.turning_scans < config.min_turning_scans || turning_pairs < config.min_turning_pairs) {
    std::ostringstream why;
    why << "too little turning to tell the timing: " << estimate.turning_scans << " scans turn at "
        << config.turning_rate << " rad/s or faster (fastest " << formatSeconds(estimate.fastest_turn)
        << " rad/s), " << turning_pairs << " overlapping pairs with a turning scan; at least "
        << config.min_turning_scans << " turning scans and " << config.min_turning_pairs
        << " such pairs are needed (turn at 0.5-2 rad/s for a few seconds, starting and stopping, "
           "in sight of the same walls)";
    estimate.why = why.str();
    return estimate;
  }

  // Every beam order and candidate period: coarse offsets over +-1.25 periods, then fine round the best.
  struct Candidate {
    Curve coarse;
    Curve fine;
    double offset = 0.0;
    double value = 0.0;
    double period = 0.0;
  };
  std::vector<Candidate> candidates;
  for (double period : periods) {
    for (BeamOrder order : {BeamOrder::kAsMessage, BeamOrder::kReversed}) {
      TimingConfig timing;
      timing.beam_order = order;
      timing.scan_period = period;
      timing.use_scan_period = true;
      // +-1.25 periods and at least +-100 ms (fast sensors, long latencies), in at most 49 steps.
      const double range = std::max(1.25 * period, config.min_range);
      const double coarse_step = std::max(period / 24.0, range / 24.0);
      Candidate candidate;
      candidate.coarse = evaluate(fit, timing, grid(0.0, range, coarse_step), cap);
      const double best = minimumOf(candidate.coarse.offsets, candidate.coarse.mean).first;
      const double fine_step = std::min(config.resolution * 5.0, coarse_step / 4.0);
      candidate.period = period;
      candidate.fine = evaluate(fit, timing, grid(best, 1.5 * coarse_step, fine_step), cap);
      std::tie(candidate.offset, candidate.value) = minimumOf(candidate.fine.offsets, candidate.fine.mean);
      candidates.push_back(std::move(candidate));
    }
  }
  const auto best =
      std::min_element(candidates.begin(), candidates.end(),
                       [](const Candidate& a, const Candidate& b) { return a.value < b.value; });
  // The best of the other beam order, for its confidence.
  const Candidate* rival = nullptr;
  for (const Candidate& candidate : candidates) {
    if (candidate.fine.timing.beam_order != best->fine.timing.beam_order &&
        (!rival || candidate.value < rival->value))
      rival = &candidate;
  }

  // Bootstrap over the scans: a resample draws scans with replacement; a pair counts as often as its
  // later scan was drawn. Each resample's minimum is sought over the whole coarse range, then, when it
  // falls in the fine window, on the fine grid: a flat or two-valleyed score shows as a wide spread.
  const auto resampledMinimum = [](const Candidate& candidate, const std::vector<double>& weights) {
    const std::vector<double> coarse = weightedMeans(candidate.coarse, weights);
    const auto [at, value] = minimumOf(candidate.coarse.offsets, coarse);
    if (at < candidate.fine.offsets.front() || at > candidate.fine.offsets.back())
      return std::make_pair(at, value);
    return minimumOf(candidate.fine.offsets, weightedMeans(candidate.fine, weights));
  };
  std::mt19937 random(config.seed);
  std::uniform_int_distribution<std::size_t> draw(0, fit.scanCount() - 1);
  std::vector<double> offsets;
  std::size_t order_held = 0;
  const auto& pairs = fit.pairs();
  for (std::size_t r = 0; r < std::max<std::size_t>(2, config.resamples); ++r) {
    std::vector<double> drawn(fit.scanCount(), 0.0);
    for (std::size_t k = 0; k < fit.scanCount(); ++k)
      drawn[draw(random)] += 1.0;
    std::vector<double> weights(pairs.size());
    double total = 0.0;
    for (std::size_t p = 0; p < pairs.size(); ++p)
      total += weights[p] = drawn[pairs[p].second];
    if (total <= 0.0)
      continue;  // no pair drawn: nothing to say
    const auto [offset, value] = resampledMinimum(*best, weights);
    offsets.push_back(offset);
    if (!rival || value < resampledMinimum(*rival, weights).second)
      ++order_held;
  }
  if (offsets.size() < 2) {
    estimate.why = "too few pairs to tell the timing";
    return estimate;
  }
  estimate.offset_sigma = summarize(offsets).spread;
  estimate.order_confidence = static_cast<double>(order_held) / offsets.size();
  estimate.time_offset = best->offset;
  estimate.period = best->period;
  estimate.period_estimated = best->period != estimate.message_period;
  estimate.period_sigma = estimate.period_estimated ? fit.nominalPeriodSigma() : 0.0;

  if (estimate.offset_sigma > config.max_uncertainty_share * estimate.period ||
      estimate.order_confidence < 0.9) {
    std::ostringstream why;
    why << "the recording cannot tell the timing well enough: offset " << formatSeconds(best->offset * 1e3)
        << " ms +- " << formatSeconds(estimate.offset_sigma * 1e3) << " ms, beam order held in "
        << formatSeconds(estimate.order_confidence * 100.0) << " % of resamples; " << estimate.turning_scans
        << " scans turn at " << config.turning_rate
        << " rad/s or faster. Record more turning (0.5-2 rad/s, starting and stopping, in sight of the same "
           "walls)";
    estimate.why = why.str();
    return estimate;
  }
  estimate.told = true;

  // As parameters: snapped to "as the message says" or to "stamped at the end" when that close.
  TimingConfig& timing = estimate.timing;
  timing.beam_order = best->fine.timing.beam_order;
  if (estimate.period_estimated) {
    timing.scan_period = estimate.period;
    timing.use_scan_period = estimate.message_period > 0.0;
  }
  const PlanarScan& first = fit.scan(0);
  const double sweep = estimate.sweep =
      estimate.period * std::abs(static_cast<double>(first.angle_increment)) / kTwoPi *
      static_cast<double>(first.ranges.empty() ? 0 : first.ranges.size() - 1);
  const double tolerance = std::max(config.snap, 2.0 * estimate.offset_sigma);
  if (std::abs(estimate.time_offset) <= tolerance) {
    timing.time_offset = 0.0;
  } else if (std::abs(estimate.time_offset + sweep) <= tolerance) {
    timing.stamp_at = StampAt::kEnd;
    timing.time_offset = 0.0;
  } else {
    timing.time_offset = std::round(estimate.time_offset * 1e5) / 1e5;  // 10 us
  }
  estimate.changed = timing.beam_order != BeamOrder::kAsMessage || timing.stamp_at != StampAt::kStart ||
                     timing.time_offset != 0.0 || estimate.period_estimated;
  estimate.after = summarize(fit.pairDistances(timing));
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
  try {
    const BeamTiming beams = resolveTiming(scan, configured_);
    const TimeNs begin = beams.earliestBeamTime();
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
    entry.turn_rate = std::abs(turnRate(motion, begin, end));
    // Every return corrected, every k-th placed: at most config_.beams a scan.
    const std::size_t stride = std::max<std::size_t>(
        1, (scan.ranges.size() + config_.beams - 1) / std::max<std::size_t>(1, config_.beams));
    for (const BeamTiming& beams_of_timing : resolved) {
      deskewer_.deskew(scan, beams_of_timing, mount, motion, corrected_);
      entry.placed.push_back(placeCorrected(corrected_, motion.basePose(corrected_.reference_time) + mount,
                                            std::abs(static_cast<double>(scan.angle_increment)), stride));
    }
  } catch (const MotionUnavailable&) {
    // Not yet covered: it waits for later tf, unless a newer scan behind it already is (then tf will
    // never cover it: it is left out).
    if (pending_.size() > 1 && pending_.back().scan.stamp - scan.stamp > secondsToNs(1.0))
      pending_.pop_front();
    return false;
  } catch (const InvalidInput&) {
    pending_.pop_front();
    return false;
  }
  pending_.pop_front();
  timings_ = std::move(timings);
  ++scans_;
  // Partners: spread over the history, the newest first.
  const TimeNs horizon = entry.time - secondsToNs(config_.history);
  history_.erase(
      std::remove_if(history_.begin(), history_.end(),
                     [&](const Entry& old) { return old.time < horizon || old.time >= entry.time; }),
      history_.end());
  const std::size_t count = std::min(config_.partners, history_.size());
  for (std::size_t k = 0; k < count; ++k) {
    const Entry& partner = history_[history_.size() - 1 - spreadIndex(k, count, history_.size())];
    if (std::max(partner.turn_rate, entry.turn_rate) < config_.turning_rate)
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

TimingCheck::Verdict TimingCheck::verdict() const {
  Verdict verdict;
  verdict.pairs = pairs_;
  if (pairs_ < config_.min_pairs || timings_.empty())
    return verdict;
  std::size_t best = 1;
  for (std::size_t t = 2; t < sums_.size(); ++t) {
    if (sums_[t] < sums_[best])
      best = t;
  }
  verdict.configured = sums_[0] / pairs_;
  verdict.best = sums_[best] / pairs_;
  verdict.best_name = timings_[best].first;
  char text[320];
  if (verdict.best < config_.margin * verdict.configured &&
      wins_[best] >= config_.min_win_share * static_cast<double>(pairs_)) {
    verdict.state = State::kBetter;
    std::snprintf(text, sizeof text,
                  "timing fits markedly better with %s: overlapping scans %.1f mm apart against %.1f mm as "
                  "configured (%zu pairs while turning); check with deskew_calibrate",
                  verdict.best_name.c_str(), verdict.best * 1e3, verdict.configured * 1e3, pairs_);
  } else {
    verdict.state = State::kFits;
    std::snprintf(text, sizeof text,
                  "timing fits: overlapping scans %.1f mm apart (best alternative, %s: %.1f mm; %zu pairs "
                  "while turning)",
                  verdict.configured * 1e3, verdict.best_name.c_str(), verdict.best * 1e3, pairs_);
  }
  verdict.message = text;
  return verdict;
}

}  // namespace lidar_deskew::core
