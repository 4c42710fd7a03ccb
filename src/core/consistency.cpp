#include "lidar_deskew/core/consistency.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fast_atan2.h"
#include "simd.h"

namespace lidar_deskew::core {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr int kBinReach = 2;  // bins searched on either side of the query's
using detail::fastAtan2;

/// `pose`.composePoint() in the x-y plane, inline: the same products and sums in the same order (MRPT's
/// is an out-of-line call with optional Jacobians, per point).
class PlanarCompose {
 public:
  explicit PlanarCompose(const mrpt::poses::CPose3D& pose)
      : r00_(pose.getRotationMatrix()(0, 0)), r01_(pose.getRotationMatrix()(0, 1)),
        r02_(pose.getRotationMatrix()(0, 2)), r10_(pose.getRotationMatrix()(1, 0)),
        r11_(pose.getRotationMatrix()(1, 1)), r12_(pose.getRotationMatrix()(1, 2)), x_(pose.x()), y_(pose.y()) {}
  Eigen::Vector2d operator()(double x, double y, double z) const {
    return {r00_ * x + r01_ * y + r02_ * z + x_, r10_ * x + r11_ * y + r12_ * z + y_};
  }

 private:
  double r00_, r01_, r02_, r10_, r11_, r12_, x_, y_;
};

/// The bin of a point at (x, y) from the origin, of `bins` round the circle.
std::size_t binAt(double x, double y, double inverse_bin_width, std::size_t bins) {
  const double bearing = fastAtan2(y, x) + M_PI;  // [0, 2pi]
  const auto bin = static_cast<std::size_t>(std::max(0.0, bearing * inverse_bin_width));
  return bin >= bins ? bin - bins : bin;
}

/// binAt() of `count` points (every `stride`-th from `points`) at once into `bins_of`, two at a time in
/// SSE2 lanes (fastAtan2()'s two-lane form: the same bits), the bins being fewer than 2^31.
void binsOf(const Eigen::Vector2d* points, std::size_t count, std::size_t stride,
            const Eigen::Vector2d& origin, double inverse_bin_width, std::size_t bins,
            std::uint32_t* bins_of) {
  std::size_t i = 0;
#if defined(__SSE2__)
  const __m128d zero = _mm_setzero_pd(), pi = _mm_set1_pd(M_PI);
  const __m128d origin_x = _mm_set1_pd(origin.x()), origin_y = _mm_set1_pd(origin.y());
  const __m128d inverse = _mm_set1_pd(inverse_bin_width);
  for (; i + 1 < count; i += 2) {
    const __m128d first = _mm_loadu_pd(points[i * stride].data());
    const __m128d second = _mm_loadu_pd(points[(i + 1) * stride].data());
    const __m128d x = _mm_sub_pd(_mm_unpacklo_pd(first, second), origin_x);
    const __m128d y = _mm_sub_pd(_mm_unpackhi_pd(first, second), origin_y);
    const __m128d r = fastAtan2(y, x);
    const __m128d scaled = _mm_mul_pd(_mm_add_pd(r, pi), inverse);
    const __m128i truncated = _mm_cvttpd_epi32(_mm_max_pd(scaled, zero));  // std::max(0.0, scaled)
    const auto wrap = [bins](int bin) {
      return static_cast<std::uint32_t>(static_cast<std::size_t>(bin) >= bins ? bin - bins : bin);
    };
    bins_of[i] = wrap(_mm_cvtsi128_si32(truncated));
    bins_of[i + 1] = wrap(_mm_cvtsi128_si32(_mm_srli_si128(truncated, 4)));
  }
#endif
  for (; i < count; ++i) {
    const Eigen::Vector2d& point = points[i * stride];
    bins_of[i] = static_cast<std::uint32_t>(
        binAt(point.x() - origin.x(), point.y() - origin.y(), inverse_bin_width, bins));
  }
}

}  // namespace

PlacedScan::PlacedScan(TimeNs time, const Eigen::Vector2d& origin, double bearing_step,
                       std::vector<Eigen::Vector2d> points)
    : points_(std::move(points)) {
  checkBearingStep(bearing_step);
  index(time, origin, bearing_step);
}

void PlacedScan::checkBearingStep(double bearing_step) {
  if (!(bearing_step > 0.0) || !std::isfinite(bearing_step))
    throw InvalidInput("bearing_step", "must be a positive angle");
}

void PlacedScan::index(TimeNs time, const Eigen::Vector2d& origin, double bearing_step) {
  time_ = time;
  origin_ = origin;
  // Bins of one bearing step, at most 2^16 round the circle.
  bin_width_ = std::max(bearing_step, kTwoPi / 65536.0);
  inverse_bin_width_ = 1.0 / bin_width_;
  const std::size_t bins = static_cast<std::size_t>(std::ceil(kTwoPi / bin_width_));
  // A counting sort, stable: bin_begin_[b + 1] counts bin b's points, then (summed) is where bin b + 1
  // begins; each point goes to its bin's cursor bin_begin_[b], which so ends at bin b's end (bin b + 1's
  // begin), and the whole is moved up by one.
  std::vector<std::uint32_t>& bin_of = bin_of_;
  bin_begin_.assign(bins + 1, 0);
  bin_of.resize(points_.size());
  binsOf(points_.data(), points_.size(), 1, origin_, inverse_bin_width_, bins, bin_of.data());
  for (std::size_t i = 0; i < points_.size(); ++i)
    ++bin_begin_[bin_of[i] + 1];
  for (std::size_t b = 0; b < bins; ++b)
    bin_begin_[b + 1] += bin_begin_[b];
  by_bin_.resize(points_.size());
  binned_.resize(points_.size());
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const std::uint32_t k = bin_begin_[bin_of[i]]++;
    by_bin_[k] = static_cast<std::uint32_t>(i);
    binned_[k] = points_[i];
  }
  for (std::size_t b = bins; b > 0; --b)
    bin_begin_[b] = bin_begin_[b - 1];
  bin_begin_[0] = 0;
}

std::size_t PlacedScan::binOf(const Eigen::Vector2d& point) const {
  return binAt(point.x() - origin_.x(), point.y() - origin_.y(), inverse_bin_width_, bin_begin_.size() - 1);
}

bool PlacedScan::distanceToContour(const Eigen::Vector2d& query, double radius, double& distance,
                                   double& nearest) const {
  ContourHit hit;
  if (!contourHit(query, radius, hit))
    return false;
  distance = hit.distance;
  nearest = hit.nearest;
  return true;
}

bool PlacedScan::contourHit(const Eigen::Vector2d& query, double radius, ContourHit& hit) const {
  if (points_.empty())
    return false;
  if (!indexed_)
    throw std::logic_error("PlacedScan: looked up in, but assigned without its index");
  return contourHitIn(binOf(query), query, radius, hit);
}

std::size_t PlacedScan::sumDistancesToContour(const std::vector<Eigen::Vector2d>& queries, std::size_t stride,
                                              double radius, double cap, double& sum) const {
  if (points_.empty())
    return 0;
  if (!indexed_)
    throw std::logic_error("PlacedScan: looked up in, but assigned without its index");
  constexpr std::size_t kChunk = 64;
  std::uint32_t bins[kChunk];
  std::size_t found = 0;
  ContourHit hit;
  const std::size_t count = (queries.size() + stride - 1) / stride;
  for (std::size_t begin = 0; begin < count; begin += kChunk) {
    const std::size_t chunk = std::min(kChunk, count - begin);
    binsOf(queries.data() + begin * stride, chunk, stride, origin_, inverse_bin_width_, bin_begin_.size() - 1,
           bins);
    for (std::size_t k = 0; k < chunk; ++k) {
      if (!contourHitIn(bins[k], queries[(begin + k) * stride], radius, hit))
        continue;
      sum += std::min(hit.distance, cap);
      ++found;
    }
  }
  return found;
}

bool PlacedScan::contourHitIn(std::size_t query_bin, const Eigen::Vector2d& query, double radius,
                              ContourHit& hit) const {
  const auto bins = static_cast<std::ptrdiff_t>(bin_begin_.size() - 1);
  std::ptrdiff_t first = static_cast<std::ptrdiff_t>(query_bin) - kBinReach;  // binOf() < bins
  while (first < 0)
    first += bins;
  double best = radius * radius;
  std::ptrdiff_t found = -1;  // in bin order; the last of equally near points in the bins' order
  // The bins searched are consecutive, so their points are one run of binned_ (two where they wrap).
  const auto search = [&](std::uint32_t begin, std::uint32_t end) {
    for (std::uint32_t k = begin; k < end; ++k) {
      const double dx = binned_[k].x() - query.x(), dy = binned_[k].y() - query.y();
      const double squared = dx * dx + dy * dy;
      if (squared <= best) {
        best = squared;
        found = k;
      }
    }
  };
  constexpr std::ptrdiff_t kSearched = 2 * kBinReach + 1;
  if (bins >= kSearched) {
    const std::ptrdiff_t end = first + kSearched;
    if (end <= bins) {
      search(bin_begin_[first], bin_begin_[end]);
    } else {
      search(bin_begin_[first], bin_begin_[bins]);
      search(bin_begin_[0], bin_begin_[end - bins]);
    }
  } else {  // fewer bins than searched: some are searched twice, in the same order as ever
    for (std::ptrdiff_t step = 0, bin = first; step < kSearched; ++step, bin = bin + 1 == bins ? 0 : bin + 1)
      search(bin_begin_[bin], bin_begin_[bin + 1]);
  }
  if (found < 0)
    return false;
  found = by_bin_[found];
  const Eigen::Vector2d& point = points_[found];
  hit.point = point;
  hit.nearest = std::sqrt(best);
  hit.distance = hit.nearest;
  hit.normal.setZero();
  // Contour neighbours: consecutive points closer than the join distance.
  const double join = 0.05 + 5.0 * (point - origin_).norm() * bin_width_;
  const auto joined = [&](std::ptrdiff_t other) {
    return other >= 0 && other < static_cast<std::ptrdiff_t>(points_.size()) &&
           (points_[other] - point).squaredNorm() <= join * join;
  };
  const bool before = joined(found - 1);
  const bool after = joined(found + 1);
  if (!before && !after)
    return true;
  const Eigen::Vector2d direction =
      (after ? points_[found + 1] : point) - (before ? points_[found - 1] : point);
  const double length = direction.norm();
  if (length <= 0.0)
    return true;
  const Eigen::Vector2d offset = query - point;
  hit.distance = std::abs(direction.x() * offset.y() - direction.y() * offset.x()) / length;
  hit.normal = Eigen::Vector2d(-direction.y(), direction.x()) / length;
  return true;
}

PlacedScan placeCorrected(const DeskewedScan& corrected, const mrpt::poses::CPose3D& laser,
                          double bearing_step, std::size_t stride) {
  PlacedScan placed;
  placeCorrected(corrected, laser, bearing_step, stride, placed);
  return placed;
}

void placeCorrected(const DeskewedScan& corrected, const mrpt::poses::CPose3D& laser, double bearing_step,
                    std::size_t stride, PlacedScan& placed, bool indexed) {
  stride = std::max<std::size_t>(1, stride);
  placed.assign(corrected.reference_time, {laser.x(), laser.y()}, bearing_step * static_cast<double>(stride),
                [&](std::vector<Eigen::Vector2d>& points) {
                  const PlanarCompose compose(laser);
                  const std::size_t count = corrected.points.size();
                  points.reserve(count / stride + 1);
                  for (std::size_t i = 0; i < count; i += stride) {
                    const Eigen::Vector3d& position = corrected.points[i].position;
                    points.push_back(compose(position.x(), position.y(), position.z()));
                  }
                },
                indexed);
}

PlacedScan placeRaw(const PlanarScan& scan, const mrpt::poses::CPose3D& laser, TimeNs time,
                    std::size_t stride) {
  stride = std::max<std::size_t>(1, stride);
  const ReturnTest is_return(scan);
  const PlanarCompose compose(laser);
  std::vector<Eigen::Vector2d> points;
  std::size_t returns = 0;
  for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!is_return(scan.ranges[i]) || returns++ % stride != 0)
      continue;
    const double angle = scan.angle_min + static_cast<double>(i) * scan.angle_increment;
    points.push_back(compose(scan.ranges[i] * std::cos(angle), scan.ranges[i] * std::sin(angle), 0.0));
  }
  return PlacedScan(time, {laser.x(), laser.y()},
                    std::abs(static_cast<double>(scan.angle_increment)) * static_cast<double>(stride),
                    std::move(points));
}

double pairDistance(const PlacedScan& scan, const PlacedScan& other, const ConsistencyConfig& config,
                    double* overlap) {
  const std::vector<Eigen::Vector2d>& points = scan.points();
  const std::size_t stride =
      std::max<std::size_t>(1, (points.size() + config.max_points - 1) / config.max_points);
  double sum = 0.0;
  const std::size_t used = (points.size() + stride - 1) / stride;
  const std::size_t overlapping =
      other.sumDistancesToContour(points, stride, config.overlap_radius, config.cap, sum);
  if (overlap)
    *overlap = used ? static_cast<double>(overlapping) / used : 0.0;
  return overlapping ? sum / overlapping : std::numeric_limits<double>::quiet_NaN();
}

std::vector<std::pair<std::size_t, std::size_t>> overlappingPairs(const std::vector<PlacedScan>& scans,
                                                                  const PairSelection& selection,
                                                                  const ConsistencyConfig& config,
                                                                  const std::vector<bool>& eligible) {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  const auto usable = [&](std::size_t i) { return !scans[i].empty() && (eligible.empty() || eligible[i]); };
  const TimeNs window = secondsToNs(selection.max_interval);
  std::vector<std::size_t> near;
  for (std::size_t later = 0; later < scans.size(); ++later) {
    if (!usable(later))
      continue;
    near.clear();
    for (std::size_t earlier = later; earlier-- > 0;) {
      if (!usable(earlier))
        continue;  // (an empty scan has no time)
      if (scans[later].time() - scans[earlier].time() > window)
        break;
      if ((scans[later].origin() - scans[earlier].origin()).norm() <= selection.max_baseline)
        near.push_back(earlier);
    }
    if (near.empty())
      continue;
    // Evenly spread over the candidates: the nearest in time, the farthest, and between.
    const std::size_t count = std::min(selection.partners, near.size());
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t earlier = near[spreadIndex(k, count, near.size())];
      double overlap = 0.0;
      pairDistance(scans[later], scans[earlier], config, &overlap);
      if (overlap >= config.min_overlap)
        pairs.emplace_back(earlier, later);
    }
  }
  return pairs;
}

ConsistencySummary summarize(const std::vector<double>& pair_distances) {
  std::vector<double> values;
  for (double value : pair_distances) {
    if (std::isfinite(value))
      values.push_back(value);
  }
  ConsistencySummary summary;
  summary.pairs = values.size();
  if (values.empty())
    return summary;
  double sum = 0.0;
  for (double value : values)
    sum += value;
  summary.mean = sum / values.size();
  double squares = 0.0;
  for (double value : values)
    squares += (value - summary.mean) * (value - summary.mean);
  summary.spread = values.size() > 1 ? std::sqrt(squares / (values.size() - 1)) : 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  summary.median = values[values.size() / 2];
  return summary;
}

}  // namespace lidar_deskew::core
