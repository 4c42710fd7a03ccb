#include "lidar_deskew/core/scan_match.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "lidar_deskew/core/types.h"

namespace lidar_deskew::core {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double wrapAngle(double angle) {
  return std::atan2(std::sin(angle), std::cos(angle));
}

std::size_t strideFor(std::size_t size, std::size_t wanted) {
  return std::max<std::size_t>(1, (size + wanted - 1) / std::max<std::size_t>(1, wanted));
}

// One Gauss-Newton step of point-to-line ICP with a Cauchy kernel (point-to-point where the contour has
// no line). Returns the correspondences found; moves `pose` and sets `step` [m or rad] when there
// were enough.
std::size_t icpStep(const PlacedScan& reference, const std::vector<Eigen::Vector2d>& moving,
                    std::size_t stride, double radius, double kernel, Pose2d& pose, double& step) {
  const double cosine = std::cos(pose.yaw), sine = std::sin(pose.yaw);
  const double inverse_kernel_squared = 1.0 / (kernel * kernel);
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  std::size_t found = 0;
  PlacedScan::ContourHit hit;
  for (std::size_t i = 0; i < moving.size(); i += stride) {
    const Eigen::Vector2d rotated(cosine * moving[i].x() - sine * moving[i].y(),
                                  sine * moving[i].x() + cosine * moving[i].y());
    const Eigen::Vector2d query(rotated.x() + pose.x, rotated.y() + pose.y);
    if (!reference.contourHit(query, radius, hit))
      continue;
    ++found;
    const auto add = [&](const Eigen::Vector2d& normal) {
      const double residual = normal.dot(query - hit.point);
      const Eigen::Vector3d jacobian(normal.x(), normal.y(),
                                     normal.y() * rotated.x() - normal.x() * rotated.y());
      const double weight = 1.0 / (1.0 + residual * residual * inverse_kernel_squared);
      normal_matrix.noalias() += weight * jacobian * jacobian.transpose();
      gradient.noalias() += weight * residual * jacobian;
    };
    if (hit.normal.isZero()) {
      add(Eigen::Vector2d::UnitX());
      add(Eigen::Vector2d::UnitY());
    } else {
      add(hit.normal);
    }
  }
  if (found < 3)
    return found;
  // A little damping: a corridor leaves the translation along it free.
  normal_matrix.diagonal().array() += 1e-6 * normal_matrix.trace() + 1e-12;
  const Eigen::Vector3d delta = -normal_matrix.ldlt().solve(gradient);
  if (!delta.allFinite())
    return 0;
  pose.x += delta(0);
  pose.y += delta(1);
  pose.yaw = wrapAngle(pose.yaw + delta(2));
  step = delta.cwiseAbs().maxCoeff();
  return found;
}

// The coarse search's score: the mean of min(point-to-contour distance, cap) over the moving points
// used, a point without a correspondence within `radius` counting as cap.
double coarseScore(const PlacedScan& reference, const std::vector<Eigen::Vector2d>& moving,
                   std::size_t stride, const Pose2d& pose, double radius, double cap) {
  double sum = 0.0;
  std::size_t used = 0;
  for (std::size_t i = 0; i < moving.size(); i += stride, ++used) {
    double distance, nearest;
    const bool hit = reference.distanceToContour(pose.apply(moving[i]), radius, distance, nearest);
    sum += hit ? std::min(distance, cap) : cap;
  }
  return used ? sum / used : std::numeric_limits<double>::infinity();
}

double median(std::vector<double> values) {
  if (values.empty())
    return kNaN;
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

double quantile(std::vector<double> values, double share) {
  if (values.empty())
    return kNaN;
  std::sort(values.begin(), values.end());
  const double position = share * static_cast<double>(values.size() - 1);
  const auto below = static_cast<std::size_t>(position);
  const std::size_t above = std::min(below + 1, values.size() - 1);
  return values[below] + (position - static_cast<double>(below)) * (values[above] - values[below]);
}

// The least-squares scale through 0 of `matched` on `told`, and their correlation (NaN when undefined).
void fitRotation(const std::vector<double>& told, const std::vector<double>& matched, double& scale,
                 double& correlation) {
  scale = correlation = kNaN;
  if (matched.empty())
    return;
  double tt = 0.0, tm = 0.0, mean_t = 0.0, mean_m = 0.0;
  for (std::size_t k = 0; k < matched.size(); ++k) {
    tt += told[k] * told[k];
    tm += told[k] * matched[k];
    mean_t += told[k];
    mean_m += matched[k];
  }
  mean_t /= matched.size();
  mean_m /= matched.size();
  double vt = 0.0, vm = 0.0, covariance = 0.0;
  for (std::size_t k = 0; k < matched.size(); ++k) {
    vt += (told[k] - mean_t) * (told[k] - mean_t);
    vm += (matched[k] - mean_m) * (matched[k] - mean_m);
    covariance += (told[k] - mean_t) * (matched[k] - mean_m);
  }
  if (tt > 0.0)
    scale = tm / tt;
  if (vt > 0.0 && vm > 0.0)
    correlation = covariance / std::sqrt(vt * vm);
}

PlacedScan inOwnFrame(const PlanarScan& scan) {
  try {
    return placeRaw(scan, mrpt::poses::CPose3D(), scan.stamp);
  } catch (const InvalidInput&) {
    return PlacedScan();  // no angle step
  }
}

}  // namespace

Eigen::Vector2d Pose2d::apply(const Eigen::Vector2d& point) const {
  const double cosine = std::cos(yaw), sine = std::sin(yaw);
  return {cosine * point.x() - sine * point.y() + x, sine * point.x() + cosine * point.y() + y};
}

Pose2d Pose2d::compose(const Pose2d& other) const {
  const Eigen::Vector2d position = apply({other.x, other.y});
  return {position.x(), position.y(), wrapAngle(yaw + other.yaw)};
}

ScanMatch matchScans(const PlacedScan& reference, const std::vector<Eigen::Vector2d>& moving,
                     const Pose2d& guess, const ScanMatchConfig& config) {
  ScanMatch match;
  match.distance = kNaN;
  if (reference.empty() || moving.size() < 10)
    return match;
  // Coarse: rotations round the guess, each given a few iterations to find its translation.
  const std::size_t coarse_stride = strideFor(moving.size(), config.coarse_points);
  const int candidates = config.rotation_step > 0.0
                             ? static_cast<int>(std::floor(config.rotation_search / config.rotation_step))
                             : 0;
  double best_score = std::numeric_limits<double>::infinity();
  Pose2d best = guess;
  for (int k = -candidates; k <= candidates; ++k) {
    Pose2d pose{guess.x, guess.y, wrapAngle(guess.yaw + k * config.rotation_step)};
    double step = 0.0;
    for (std::size_t i = 0; i < config.coarse_iterations; ++i)
      icpStep(reference, moving, coarse_stride, config.radius, config.radius / 4.0, pose, step);
    const double score =
        coarseScore(reference, moving, coarse_stride, pose, config.radius, config.final_radius);
    if (score < best_score) {
      best_score = score;
      best = pose;
    }
  }
  // Refine: the radius and the kernel shrink, then iterate until the step is negligible.
  const std::size_t stride = strideFor(moving.size(), config.max_points);
  double radius = config.radius;
  double kernel = config.radius / 4.0;
  std::size_t found = 0;
  for (std::size_t i = 0; i < config.iterations; ++i) {
    double step = std::numeric_limits<double>::infinity();
    found = icpStep(reference, moving, stride, radius, kernel, best, step);
    match.iterations = i + 1;
    const bool shrinking = radius > config.final_radius || kernel > config.kernel;
    radius = std::max(config.final_radius, radius * (2.0 / 3.0));
    kernel = std::max(config.kernel, kernel * (2.0 / 3.0));
    if (found < 3 || (!shrinking && step < config.tolerance))
      break;
  }
  match.pose = best;
  const std::size_t used = (moving.size() + stride - 1) / stride;
  match.valid = found >= 10 && 3 * found >= used;
  // The aligned distance, by the consistency measure's own rule.
  std::vector<Eigen::Vector2d> aligned;
  aligned.reserve(moving.size());
  for (const Eigen::Vector2d& point : moving)
    aligned.push_back(best.apply(point));
  const PlacedScan aligned_scan(reference.time(), Eigen::Vector2d(best.x, best.y), 1.0, std::move(aligned));
  match.distance = pairDistance(aligned_scan, reference, config.score, &match.overlap);
  return match;
}

ShapeCheck::ShapeCheck(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount,
                       const MotionSource& motion, const ShapeConfig& config)
    : scans_(std::move(scans)), mount_(mount), motion_(motion), config_(config) {
  for (std::size_t i = 1; i < scans_.size(); ++i) {
    if (scans_[i].stamp < scans_[i - 1].stamp)
      throw InvalidInput("scans", "must be sorted by stamp");
  }
  const std::size_t count = scans_.size();
  raw_.reserve(count);
  for (const PlanarScan& scan : scans_)
    raw_.push_back(inOwnFrame(scan));
  const TimeNs window = secondsToNs(config_.max_interval);
  // Consecutive raw scans, matched with no guess: the rotation the scans show.
  to_previous_.assign(count, ScanMatch());
  std::vector<double> rates(count, kNaN);
  std::vector<double> rate_sum(count, 0.0);
  std::vector<int> rate_count(count, 0);
  for (std::size_t i = 1; i < count; ++i) {
    const TimeNs interval = scans_[i].stamp - scans_[i - 1].stamp;
    if (interval <= 0 || interval > window || raw_[i].empty() || raw_[i - 1].empty())
      continue;
    ScanMatch match = matchScans(raw_[i - 1], raw_[i].points(), Pose2d(), config_.match);
    if (!match.valid || !(match.overlap >= config_.min_overlap))
      continue;
    const double rate = match.pose.yaw / nsToSeconds(interval);
    for (std::size_t k : {i - 1, i}) {
      rate_sum[k] += rate;
      ++rate_count[k];
    }
    to_previous_[i] = match;
  }
  for (std::size_t i = 0; i < count; ++i) {
    if (rate_count[i] > 0)
      rates[i] = rate_sum[i] / rate_count[i];
  }
  rotation_ = rotation(TimingConfig());
  // Pairs a short time apart whose turn rates differ, linked by a chain of consecutive matches (the
  // guess: odometry does not enter).
  std::vector<std::pair<std::size_t, std::size_t>> candidates;
  std::vector<std::size_t> later;
  for (std::size_t e = 0; e < count; ++e) {
    if (!std::isfinite(rates[e]))
      continue;
    later.clear();
    for (std::size_t l = e + 1; l < count && scans_[l].stamp - scans_[e].stamp <= window; ++l) {
      if (!to_previous_[l].valid)
        break;  // the chain is broken
      if (std::isfinite(rates[l]) && std::abs(rates[l] - rates[e]) >= config_.min_turn_difference)
        later.push_back(l);
    }
    const std::size_t take = std::min(config_.partners, later.size());
    for (std::size_t k = 0; k < take; ++k)
      candidates.emplace_back(e, later[spreadIndex(k, take, later.size())]);
  }
  const std::size_t take = std::min(config_.max_pairs, candidates.size());
  for (std::size_t k = 0; k < take; ++k) {
    const auto [e, l] = candidates[spreadIndex(k, take, candidates.size())];
    Pose2d guess;
    for (std::size_t link = e + 1; link <= l; ++link)
      guess = guess.compose(to_previous_[link].pose);
    ScanMatch match = matchScans(raw_[e], raw_[l].points(), guess, config_.match);
    if (!match.valid || !(match.overlap >= config_.min_overlap))
      continue;
    pairs_.emplace_back(e, l);
    raw_matches_.push_back(match);
  }
}

TimeNs ShapeCheck::middleTime(std::size_t i, const TimingConfig& timing) const {
  try {
    const BeamTiming beams = resolveTiming(scans_[i], timing);
    return beams.earliestBeamTime() + (beams.latestBeamTime() - beams.earliestBeamTime()) / 2;
  } catch (const InvalidInput&) {
    return scans_[i].stamp + secondsToNs(timing.time_offset);  // no period: the stamp as the timing moves it
  }
}

RotationAgreement ShapeCheck::rotation(const TimingConfig& timing) const {
  RotationAgreement result;
  result.scale = result.correlation = result.lag = result.lag_scale = result.lag_correlation = kNaN;
  std::vector<std::pair<TimeNs, TimeNs>> times;
  std::vector<double> matched;
  for (std::size_t i = 1; i < scans_.size(); ++i) {
    if (!to_previous_[i].valid)
      continue;
    times.emplace_back(middleTime(i - 1, timing), middleTime(i, timing));
    matched.push_back(to_previous_[i].pose.yaw);
  }
  // tf's rotation between the scans' times + lag, beside the matched one (pairs tf does not cover left
  // out).
  std::vector<double> told, used, intervals;
  const auto compare = [&](TimeNs lag) {
    told.clear();
    used.clear();
    intervals.clear();
    for (std::size_t m = 0; m < matched.size(); ++m) {
      try {
        const mrpt::poses::CPose3D earlier = motion_.basePose(times[m].first + lag) + mount_;
        const mrpt::poses::CPose3D later = motion_.basePose(times[m].second + lag) + mount_;
        told.push_back(wrapAngle((later - earlier).yaw()));
        used.push_back(matched[m]);
        intervals.push_back(nsToSeconds(times[m].second - times[m].first));
      } catch (const MotionUnavailable&) {
      }
    }
  };
  compare(0);
  result.pairs = used.size();
  for (std::size_t k = 0; k < used.size(); ++k) {
    const double turn = config_.turning_rate * intervals[k];
    if (std::abs(told[k]) >= turn || std::abs(used[k]) >= turn)
      ++result.turning_pairs;
  }
  if (result.turning_pairs == 0)
    return result;
  fitRotation(told, used, result.scale, result.correlation);
  // The same with tf shifted in time, where it correlates best; shifts that lose more than a tenth of
  // the pairs off tf's ends are not compared.
  const int lags =
      config_.lag_step > 0.0 ? static_cast<int>(std::floor(config_.max_lag / config_.lag_step)) : 0;
  for (int k = -lags; k <= lags; ++k) {
    const TimeNs lag = secondsToNs(k * config_.lag_step);
    compare(lag);
    if (10 * used.size() < 9 * result.pairs)
      continue;
    double scale, correlation;
    fitRotation(told, used, scale, correlation);
    if (std::isfinite(correlation) && !(correlation <= result.lag_correlation)) {
      result.lag = nsToSeconds(lag);
      result.lag_scale = scale;
      result.lag_correlation = correlation;
    }
  }
  return result;
}

ShapeRatio ShapeCheck::shapes(const TimingConfig& timing, const DeskewConfig& deskew) const {
  std::vector<char> needed(scans_.size(), 0);
  for (const auto& [e, l] : pairs_)
    needed[e] = needed[l] = 1;
  ScanDeskewer deskewer(deskew);
  DeskewedScan corrected;
  std::vector<PlacedScan> placed(scans_.size());
  for (std::size_t i = 0; i < scans_.size(); ++i) {
    if (!needed[i])
      continue;
    try {
      const BeamTiming beams = resolveTiming(scans_[i], timing);
      deskewer.deskew(scans_[i], beams, mount_, motion_, corrected);
      placed[i] = placeCorrected(corrected, mrpt::poses::CPose3D(),
                                 std::abs(static_cast<double>(scans_[i].angle_increment)));
    } catch (const InvalidInput&) {
    } catch (const MotionUnavailable&) {
    }
  }
  std::vector<double> raw_distances, corrected_distances, ratios;
  for (std::size_t p = 0; p < pairs_.size(); ++p) {
    const auto [e, l] = pairs_[p];
    if (placed[e].empty() || placed[l].empty())
      continue;
    const ScanMatch match = matchScans(placed[e], placed[l].points(), raw_matches_[p].pose, config_.match);
    if (!match.valid || !(match.overlap >= config_.min_overlap) || !std::isfinite(match.distance))
      continue;
    raw_distances.push_back(raw_matches_[p].distance);
    corrected_distances.push_back(match.distance);
    if (raw_matches_[p].distance > 0.0)
      ratios.push_back(match.distance / raw_matches_[p].distance);
  }
  ShapeRatio result;
  result.pairs = raw_distances.size();
  result.raw = median(raw_distances);
  result.corrected = median(corrected_distances);
  result.ratio = result.raw > 0.0 ? result.corrected / result.raw : kNaN;
  result.ratio_low = quantile(ratios, 0.25);
  result.ratio_high = quantile(ratios, 0.75);
  return result;
}

std::vector<std::string> shapeWarnings(const ShapeRatio& shapes, const RotationAgreement& rotation,
                                       const ShapeConfig& config) {
  std::vector<std::string> warnings;
  char text[256];
  if (rotation.turning_pairs >= config.min_pairs && std::isfinite(rotation.scale)) {
    const bool scale_off =
        rotation.scale > config.max_scale_error || rotation.scale < 1.0 / config.max_scale_error;
    const bool uncorrelated = !(rotation.correlation >= config.min_correlation);
    if (scale_off || uncorrelated) {
      std::snprintf(text, sizeof text,
                    "tf's rotation does not fit the scans: scan matching sees %.2fx tf's rotation between "
                    "consecutive scans (correlation %.2f, %zu pairs, %zu turning)",
                    rotation.scale, rotation.correlation, rotation.pairs, rotation.turning_pairs);
      std::string warning = text;
      // When tf shifted in time fits, the disagreement is a time offset between tf and the scans.
      const bool lag_fits = std::isfinite(rotation.lag_scale) &&
                            rotation.lag_scale <= config.max_scale_error &&
                            rotation.lag_scale >= 1.0 / config.max_scale_error &&
                            rotation.lag_correlation >= config.min_correlation;
      if (lag_fits && std::abs(rotation.lag) >= 0.5 * config.lag_step) {
        std::snprintf(
            text, sizeof text,
            "; tf read at the scans' times %+.0f ms fits (%.2fx, correlation %.2f): the scans' times "
            "and tf's are off by that much (time_offset; deskew_calibrate)",
            rotation.lag * 1e3, rotation.lag_scale, rotation.lag_correlation);
        warning += text;
      }
      warnings.push_back(warning);
    }
  }
  if (shapes.pairs >= config.min_pairs && shapes.ratio > config.max_ratio) {
    std::snprintf(text, sizeof text,
                  "correction makes shapes worse than raw: aligned distance %.2fx raw (quartiles %.2f-%.2f, "
                  "%zu pairs)",
                  shapes.ratio, shapes.ratio_low, shapes.ratio_high, shapes.pairs);
    warnings.emplace_back(text);
  }
  return warnings;
}

ShapeVerdict checkShapes(std::vector<PlanarScan> scans, const mrpt::poses::CPose3D& mount,
                         const MotionSource& motion, const TimingConfig& timing, const DeskewConfig& deskew,
                         const ShapeConfig& config) {
  const ShapeCheck check(std::move(scans), mount, motion, config);
  ShapeVerdict verdict;
  verdict.shapes = check.shapes(timing, deskew);
  verdict.rotation = check.rotation(timing);
  verdict.warnings = shapeWarnings(verdict.shapes, verdict.rotation, config);
  return verdict;
}

RotationMonitor::RotationMonitor(const TimingConfig& timing, const RotationMonitorConfig& config)
    : timing_(timing), config_(config) {}

void RotationMonitor::reset(const TimingConfig& timing) {
  timing_ = timing;
  has_previous_ = has_pair_ = false;
  pairs_.clear();
}

bool RotationMonitor::add(const PlanarScan& scan, const mrpt::poses::CPose3D& mount,
                          const MotionSource& motion) {
  const bool due = !has_pair_ || scan.stamp - last_pair_ >= secondsToNs(config_.interval);
  const bool consecutive = has_previous_ && scan.stamp > previous_.stamp &&
                           scan.stamp - previous_.stamp <= secondsToNs(config_.shape.max_interval);
  bool matched = false;
  if (due && consecutive) {
    try {
      const auto middle = [&](const PlanarScan& of) {
        const BeamTiming beams = resolveTiming(of, timing_);
        return beams.earliestBeamTime() + (beams.latestBeamTime() - beams.earliestBeamTime()) / 2;
      };
      const TimeNs earlier_time = middle(previous_), later_time = middle(scan);
      const double told =
          wrapAngle(((motion.basePose(later_time) + mount) - (motion.basePose(earlier_time) + mount)).yaw());
      const PlacedScan earlier = inOwnFrame(previous_), later = inOwnFrame(scan);
      const ScanMatch match = matchScans(earlier, later.points(), Pose2d(), config_.shape.match);
      matched = true;
      last_pair_ = scan.stamp;
      has_pair_ = true;
      if (match.valid && match.overlap >= config_.shape.min_overlap) {
        const double turn = config_.shape.turning_rate * nsToSeconds(later_time - earlier_time);
        pairs_.push_back({match.pose.yaw, told, std::abs(told) >= turn || std::abs(match.pose.yaw) >= turn});
        if (pairs_.size() > config_.history)
          pairs_.pop_front();
      }
    } catch (const InvalidInput&) {
    } catch (const MotionUnavailable&) {
    }
  }
  previous_ = scan;
  has_previous_ = true;
  return matched;
}

RotationAgreement RotationMonitor::agreement() const {
  RotationAgreement result;
  result.scale = result.correlation = result.lag = result.lag_scale = result.lag_correlation = kNaN;
  std::vector<double> matched, told;
  for (const Pair& pair : pairs_) {
    matched.push_back(pair.matched);
    told.push_back(pair.told);
    result.turning_pairs += pair.turning ? 1 : 0;
  }
  result.pairs = pairs_.size();
  if (result.turning_pairs > 0)
    fitRotation(told, matched, result.scale, result.correlation);
  return result;
}

std::vector<std::string> RotationMonitor::warnings() const {
  return shapeWarnings(ShapeRatio(), agreement(), config_.shape);
}

}  // namespace lidar_deskew::core
