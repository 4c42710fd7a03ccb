#include "lidar_deskew/sim/sim.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace lidar_deskew::sim {
namespace {

double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

}  // namespace

ErrorStats errorStats(std::vector<double> errors) {
  ErrorStats stats;
  stats.count = errors.size();
  if (errors.empty())
    return stats;
  double sum_squares = 0.0;
  for (double error : errors)
    sum_squares += error * error;
  std::sort(errors.begin(), errors.end());
  stats.rms = std::sqrt(sum_squares / static_cast<double>(errors.size()));
  stats.p95 = errors[static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(errors.size()))) - 1];
  stats.max = errors.back();
  return stats;
}

Pose2 Pose2::compose(const Pose2& local) const {
  const Eigen::Vector2d position = apply(Eigen::Vector2d(local.x, local.y));
  return {position.x(), position.y(), yaw + local.yaw};
}

Eigen::Vector2d Pose2::apply(const Eigen::Vector2d& local) const {
  const double c = std::cos(yaw), s = std::sin(yaw);
  return {x + c * local.x() - s * local.y(), y + s * local.x() + c * local.y()};
}

Eigen::Vector2d Pose2::applyInverse(const Eigen::Vector2d& global) const {
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double dx = global.x() - x, dy = global.y() - y;
  return {c * dx + s * dy, -s * dx + c * dy};
}

Pose2 Pose2::between(const Pose2& later) const {
  const Eigen::Vector2d position = applyInverse(Eigen::Vector2d(later.x, later.y));
  return {position.x(), position.y(), std::remainder(later.yaw - yaw, 2.0 * M_PI)};
}

void World::addPolygon(const std::vector<Eigen::Vector2d>& corners) {
  for (std::size_t i = 0; i < corners.size(); ++i)
    add(corners[i], corners[(i + 1) % corners.size()]);
}

void World::addOutline(const std::vector<Eigen::Vector2d>& corners) {
  addPolygon(corners);
  outline_ = corners;
}

bool World::insideOutline(const Eigen::Vector2d& point) const {
  // Even-odd rule: count the outline's edges crossed by a ray from the point towards +x.
  bool inside = false;
  for (std::size_t i = 0; i < outline_.size(); ++i) {
    const Eigen::Vector2d& a = outline_[i];
    const Eigen::Vector2d& b = outline_[(i + 1) % outline_.size()];
    if ((a.y() > point.y()) != (b.y() > point.y()) &&
        point.x() < a.x() + (b.x() - a.x()) * (point.y() - a.y()) / (b.y() - a.y())) {
      inside = !inside;
    }
  }
  return inside;
}

std::optional<double> raySegmentRange(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction,
                                      const Segment& segment) {
  // origin + r direction = a + u (b - a)
  const Eigen::Vector2d edge = segment.b - segment.a;
  const double denominator = cross(direction, edge);
  if (denominator == 0.0)
    return std::nullopt;
  const Eigen::Vector2d to_a = segment.a - origin;
  const double range = cross(to_a, edge) / denominator;
  const double u = cross(to_a, direction) / denominator;
  if (range > 0.0 && u >= 0.0 && u <= 1.0)
    return range;
  return std::nullopt;
}

double distanceToSegment(const Eigen::Vector2d& point, const Segment& segment) {
  const Eigen::Vector2d edge = segment.b - segment.a;
  const double u = std::clamp((point - segment.a).dot(edge) / edge.squaredNorm(), 0.0, 1.0);
  return (segment.a + u * edge - point).norm();
}

std::optional<World::Hit> World::castRayHit(const Eigen::Vector2d& origin,
                                            const Eigen::Vector2d& direction) const {
  std::optional<Hit> nearest;
  for (const Segment& segment : segments_) {
    const std::optional<double> range = raySegmentRange(origin, direction, segment);
    if (range && (!nearest || *range < nearest->range)) {
      const Eigen::Vector2d edge = segment.b - segment.a;
      nearest = Hit{*range, Eigen::Vector2d(-edge.y(), edge.x()).normalized()};
    }
  }
  return nearest;
}

std::optional<double> World::castRay(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction) const {
  const std::optional<Hit> hit = castRayHit(origin, direction);
  return hit ? std::optional<double>(hit->range) : std::nullopt;
}

double World::distanceTo(const Eigen::Vector2d& point) const {
  double nearest = std::numeric_limits<double>::infinity();
  for (const Segment& segment : segments_)
    nearest = std::min(nearest, distanceToSegment(point, segment));
  return nearest;
}

std::vector<Eigen::Vector2d> World::hallOutline() {
  // Counter-clockwise from the south-west corner; the corridor leaves the north wall between x = 4 and
  // 6.4 m and runs 6 m north; the east end is slanted.
  return {{-20.0, -5.0}, {17.0, -5.0}, {20.0, -2.0}, {20.0, 5.0},  {6.4, 5.0},
          {6.4, 11.0},   {4.0, 11.0},  {4.0, 5.0},   {-17.0, 5.0}, {-20.0, 1.5}};
}

World World::hall() {
  World world;
  world.addOutline(hallOutline());
  // Square pillars along the hall and a wall at 30 deg.
  for (const double x : {-12.0, -4.0, 8.0}) {
    world.addPolygon({{x, -2.8}, {x + 0.5, -2.8}, {x + 0.5, -2.3}, {x, -2.3}});
  }
  world.addPolygon({{-8.0, 2.5}, {-7.6, 2.5}, {-7.6, 2.9}, {-8.0, 2.9}});
  world.add({12.0, 1.0}, {12.0 + 3.0 * std::cos(M_PI / 6), 1.0 + 3.0 * std::sin(M_PI / 6)});
  return world;
}

std::vector<Eigen::Vector2d> World::smallRoomOutline() {
  // Counter-clockwise from the south-west corner; the north-east corner is cut at 45 deg.
  return {{-2.5, -2.0}, {2.5, -2.0}, {2.5, 1.0}, {1.5, 2.0}, {-2.5, 2.0}};
}

World World::smallRoom() {
  World world;
  world.addOutline(smallRoomOutline());
  world.addPolygon({{-2.2, 1.0}, {-1.9, 1.0}, {-1.9, 1.3}, {-2.2, 1.3}});
  world.add({1.2, -2.0}, {2.5, -1.2});
  return world;
}

World World::demoRoom() {
  World world;
  // Outer walls with one corner cut by a slanted wall.
  world.addPolygon({{-6.0, -4.0}, {6.0, -4.0}, {6.0, 2.5}, {4.5, 4.0}, {-6.0, 4.0}});
  // A square pillar and a free-standing wall at 30 deg.
  world.addPolygon({{2.0, -1.5}, {2.4, -1.5}, {2.4, -1.1}, {2.0, -1.1}});
  world.add({-3.5, 1.0}, {-3.5 + 2.0 * std::cos(M_PI / 6), 1.0 + 2.0 * std::sin(M_PI / 6)});
  return world;
}

Pose2 integrateUnicycle(const Pose2& start, double speed, double acceleration, double yaw_rate, double t) {
  double forward, left;  // displacement in the start frame
  if (std::abs(yaw_rate) < 1e-9) {
    forward = speed * t + 0.5 * acceleration * t * t;
    left = 0.0;
  } else {
    // With heading h(s) = w s: d/ds [ v(s) sin h / w + a cos h / w^2 ] = v(s) cos h, and
    // d/ds [ -v(s) cos h / w + a sin h / w^2 ] = v(s) sin h.
    const double heading = yaw_rate * t;
    const double speed_end = speed + acceleration * t;
    const double w2 = yaw_rate * yaw_rate;
    forward = (speed_end * std::sin(heading) / yaw_rate + acceleration * std::cos(heading) / w2) -
              (acceleration / w2);
    left = (-speed_end * std::cos(heading) / yaw_rate + acceleration * std::sin(heading) / w2) -
           (-speed / yaw_rate);
  }
  const Eigen::Vector2d position = start.apply({forward, left});
  return {position.x(), position.y(), start.yaw + yaw_rate * t};
}

PiecewiseTrajectory::PiecewiseTrajectory(const Pose2& start, std::vector<MotionPiece> pieces)
    : pieces_(std::move(pieces)) {
  if (pieces_.empty())
    pieces_.push_back({});
  starts_.push_back(start);
  begin_times_.push_back(0.0);
  for (std::size_t k = 0; k + 1 < pieces_.size(); ++k) {
    const MotionPiece& piece = pieces_[k];
    starts_.push_back(
        integrateUnicycle(starts_[k], piece.speed, piece.acceleration, piece.yaw_rate, piece.duration));
    begin_times_.push_back(begin_times_[k] + piece.duration);
  }
}

std::size_t PiecewiseTrajectory::pieceAt(double t) const {
  // The last piece that begins at or before t (the first before them all); begin_times_[0] is 0.
  const auto after = std::upper_bound(begin_times_.begin() + 1, begin_times_.end(), t);
  return static_cast<std::size_t>(after - begin_times_.begin()) - 1;
}

std::vector<MotionPiece> smoothUnicyclePieces(double speed, double yaw_rate, double duration,
                                              double speed_period, double turn_period, double piece) {
  if (!(piece > 0.0) || !(duration >= 0.0) || !(speed_period > 0.0) || !(turn_period > 0.0))
    throw std::invalid_argument("smoothUnicyclePieces: periods and piece must be > 0, duration >= 0");
  const double speed_frequency = 2.0 * M_PI / speed_period, turn_frequency = 2.0 * M_PI / turn_period;
  const auto speedAt = [&](double t) { return speed * std::cos(speed_frequency * t); };
  // The heading: the yaw rate's integral from 0.
  const auto headingAt = [&](double t) { return yaw_rate / turn_frequency * std::sin(turn_frequency * t); };
  const auto count = static_cast<std::size_t>(std::ceil(duration / piece - 1e-9));
  std::vector<MotionPiece> pieces;
  pieces.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    // Each piece's times from its index, so that rounding does not accumulate.
    const double begin = static_cast<double>(k) * piece, end = static_cast<double>(k + 1) * piece;
    pieces.push_back({end - begin, speedAt(begin), (speedAt(end) - speedAt(begin)) / (end - begin),
                      (headingAt(end) - headingAt(begin)) / (end - begin)});
  }
  return pieces;
}

Pose2 PiecewiseTrajectory::pose(double t) const {
  const std::size_t k = pieceAt(t);
  const MotionPiece& piece = pieces_[k];
  return integrateUnicycle(starts_[k], piece.speed, piece.acceleration, piece.yaw_rate, t - begin_times_[k]);
}

double PiecewiseTrajectory::speed(double t) const {
  const std::size_t k = pieceAt(t);
  return pieces_[k].speed + pieces_[k].acceleration * (t - begin_times_[k]);
}

NoisyOdometry::NoisyOdometry(const Trajectory& truth, double begin_time, double end_time,
                             double relative_noise, unsigned seed, double yaw_scale)
    : truth_(truth), begin_time_(begin_time), relative_noise_(relative_noise), yaw_scale_(yaw_scale) {
  if (!std::isfinite(relative_noise) || relative_noise < 0.0)
    throw std::invalid_argument("odom_noise: must be finite and >= 0");
  if (!std::isfinite(yaw_scale) || !(yaw_scale > 0.0))
    throw std::invalid_argument("odom_yaw_scale: must be finite and > 0");
  if (!std::isfinite(begin_time) || !std::isfinite(end_time) || end_time < begin_time)
    throw std::invalid_argument("odometry times: must be finite, end >= begin");
  const auto steps = std::max<std::size_t>(
      1, static_cast<std::size_t>(std::ceil((end_time - begin_time) / kStepDuration - 1e-9)));
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  factors_.resize(steps);
  step_truth_.push_back(truth.pose(begin_time));
  step_odometry_.push_back(step_truth_.front());
  for (std::size_t j = 0; j < steps; ++j) {
    Factors& factors = factors_[j];
    if (relative_noise > 0.0) {
      factors.x = 1.0 + relative_noise * normal(rng);
      factors.y = 1.0 + relative_noise * normal(rng);
      factors.yaw = 1.0 + relative_noise * normal(rng);
    }
    factors.yaw *= yaw_scale;
    const Pose2 next_truth = truth.pose(stepStart(j + 1));
    step_odometry_.push_back(measured(j, next_truth));
    step_truth_.push_back(next_truth);
  }
}

std::size_t NoisyOdometry::stepAt(double t) const {
  const double steps_since_begin = (t - begin_time_) / kStepDuration;
  // A time on a grid point (up to rounding) starts its step; the grid's last point ends the last step.
  if (!(steps_since_begin >= -1e-9 && steps_since_begin <= static_cast<double>(steps()) + 1e-9))
    throw std::out_of_range("odometry: time " + std::to_string(t) + " s outside its steps");
  const double step = std::floor(std::max(0.0, steps_since_begin + 1e-9));
  return std::min(static_cast<std::size_t>(step), steps() - 1);
}

Pose2 NoisyOdometry::pose(double t) const {
  const std::size_t j = stepAt(t);
  if (relative_noise_ == 0.0 && yaw_scale_ == 1.0)
    return truth_.pose(t);
  return measured(j, truth_.pose(t));
}

Pose2 NoisyOdometry::measured(std::size_t j, const Pose2& true_pose) const {
  const Pose2 increment = step_truth_[j].between(true_pose);
  const Factors& factors = factors_[j];
  return step_odometry_[j].compose(
      {increment.x * factors.x, increment.y * factors.y, increment.yaw * factors.yaw});
}

NoisyOdometry::Factors NoisyOdometry::factors(double t) const {
  return factors_[stepAt(t)];
}

float LidarModel::angleIncrement() const {
  const float magnitude = static_cast<float>(field_of_view / beams);
  return clockwise ? -magnitude : magnitude;
}

float LidarModel::angleMin() const {
  const float half = static_cast<float>(field_of_view / 2.0);
  return clockwise ? half : -half;
}

float LidarModel::timeIncrement() const {
  return static_cast<float>(std::abs(static_cast<double>(angleIncrement())) / (2.0 * M_PI) / rate);
}

double LidarModel::sweepDuration() const {
  return (beams - 1) * static_cast<double>(timeIncrement());
}

LidarModel LidarModel::utm30lx360() {
  return {"UTM-30LX", 1440, 2.0 * M_PI, 40.0, 0.030, false, 0.1f, 30.0f};
}
LidarModel LidarModel::ild26tri() {
  return {"ILD26TRI", 360, 2.0 * M_PI, 8.0, 0.060, false, 0.1f, 30.0f};
}
LidarModel LidarModel::utm30lx270() {
  return {"UTM-30LX-270", 1080, 1.5 * M_PI, 40.0, 0.030, false, 0.1f, 30.0f};
}
LidarModel LidarModel::lds01() {
  // ROBOTIS LDS-01 specification (TurtleBot3 e-manual): 300 rpm, 1 deg resolution, 120 to 3500 mm, accuracy
  // +-15 mm up to 499 mm (+-5 % beyond), precision +-10 mm up to 499 mm (+-3.5 % beyond). One sigma of 15 mm
  // sits between the short-range figures; the percentage figures are bounds, not a Gaussian sigma. Its driver
  // (hls_lfcd_lds_driver) publishes a counter-clockwise scan.
  return {"LDS-01", 360, 2.0 * M_PI, 5.0, 0.015, false, 0.12f, 3.5f};
}

void TimingFault::validate() const {
  if (!std::isfinite(stamp_error))
    throw std::invalid_argument("stamp_error: must be finite");
  if (!std::isfinite(time_increment_factor) || time_increment_factor < 0.0)
    throw std::invalid_argument("time_increment_factor: must be finite and >= 0");
}

TimingFault TimingFault::stampedAtEnd(const LidarModel& model) {
  TimingFault fault;
  fault.stamp_error = model.sweepDuration();
  return fault;
}

SimulatedScan simulateScan(const World& world, const Trajectory& trajectory, const Pose2& mount,
                           const LidarModel& model, core::TimeNs epoch, double start_time,
                           std::mt19937* noise, const TimingFault& fault) {
  fault.validate();
  SimulatedScan result;
  core::PlanarScan& scan = result.scan;
  const core::TimeNs earliest = epoch + core::secondsToNs(start_time);
  scan.stamp = earliest + core::secondsToNs(fault.stamp_error);
  scan.angle_min = model.angleMin();
  scan.angle_increment = model.angleIncrement();
  scan.angle_max =
      static_cast<float>(scan.angle_min + (model.beams - 1) * static_cast<double>(scan.angle_increment));
  const float beam_period = model.timeIncrement();
  scan.time_increment = static_cast<float>(fault.time_increment_factor * static_cast<double>(beam_period));
  scan.scan_time = fault.zero_scan_time ? 0.0f : static_cast<float>(1.0 / model.rate);
  scan.range_min = model.range_min;
  scan.range_max = model.range_max;
  std::normal_distribution<double> range_noise(0.0, model.range_sigma);
  // True beam times from the float period and the ns stamp an unfaulted message carries, so that without
  // a fault truth and message agree exactly.
  const double first_time = core::nsToSeconds(earliest - epoch);
  for (int i = 0; i < model.beams; ++i) {
    const int order = fault.reversed ? model.beams - 1 - i : i;  // place in time
    const double t = first_time + order * static_cast<double>(beam_period);
    const double angle = static_cast<double>(scan.angle_min) + i * static_cast<double>(scan.angle_increment);
    const Pose2 laser = trajectory.pose(t).compose(mount);
    const Eigen::Vector2d direction(std::cos(laser.yaw + angle), std::sin(laser.yaw + angle));
    const std::optional<double> hit = world.castRay({laser.x, laser.y}, direction);
    result.beam_times.push_back(t);
    if (hit && *hit <= model.range_max) {
      const double measured = noise ? *hit + range_noise(*noise) : *hit;
      scan.ranges.push_back(static_cast<float>(measured));
      result.world_hits.push_back(Eigen::Vector2d(laser.x, laser.y) + *hit * direction);
    } else {
      scan.ranges.push_back(std::numeric_limits<float>::infinity());
      result.world_hits.push_back(Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
    }
  }
  return result;
}

}  // namespace lidar_deskew::sim
