#include "lidar_deskew/sim/sim3d.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace lidar_deskew::sim {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Distance [m] from z to the interval [low, high] (0 inside).
double outside(double z, double low, double high) {
  return std::max({0.0, low - z, z - high});
}

/// Crossing-number test: is `point` inside the simple polygon `outline`?
bool inside(const std::vector<Eigen::Vector2d>& outline, const Eigen::Vector2d& point) {
  bool in = false;
  for (std::size_t i = 0, j = outline.size() - 1; i < outline.size(); j = i++) {
    const Eigen::Vector2d& a = outline[i];
    const Eigen::Vector2d& b = outline[j];
    if ((a.y() > point.y()) != (b.y() > point.y()) &&
        point.x() < (b.x() - a.x()) * (point.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
}

}  // namespace

Pose3 Pose3::fromXyzRpy(double x, double y, double z, double roll, double pitch, double yaw) {
  Pose3 pose;
  pose.position = {x, y, z};
  pose.rotation =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  return pose;
}

Pose3 Pose3::fromPose2(const Pose2& pose, double z) {
  return fromXyzRpy(pose.x, pose.y, z, 0.0, 0.0, pose.yaw);
}

Pose3 Pose3::compose(const Pose3& local) const {
  Pose3 result;
  result.position = apply(local.position);
  result.rotation = rotation * local.rotation;
  return result;
}

Pose3 Pose3::inverse() const {
  Pose3 result;
  result.rotation = rotation.transpose();
  result.position = -(result.rotation * position);
  return result;
}

void World3::addWall(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double z_min, double z_max) {
  walls_.push_back({a, b, z_min, z_max});
}

void World3::addExtruded(const World& plan, double z_min, double z_max) {
  for (const Segment& segment : plan.segments())
    addWall(segment.a, segment.b, z_min, z_max);
}

void World3::addHorizontal(const std::vector<Eigen::Vector2d>& outline, double z) {
  if (outline.size() < 3)
    throw std::invalid_argument("World3::addHorizontal: an outline needs 3 corners or more");
  horizontals_.push_back({outline, z});
}

void World3::addCylinder(const Eigen::Vector2d& centre, double radius, double z_min, double z_max) {
  cylinders_.push_back({centre, radius, z_min, z_max});
}

std::optional<double> World3::castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  double nearest = std::numeric_limits<double>::infinity();
  const Eigen::Vector2d origin2 = origin.head<2>();
  const Eigen::Vector2d direction2 = direction.head<2>();
  // Walls: the planar intersection's ray parameter is the 3D range (the footprint of origin + r d is
  // origin2 + r d2); then the height must be on the wall.
  for (const Wall& wall : walls_) {
    const std::optional<double> range = raySegmentRange(origin2, direction2, {wall.a, wall.b});
    if (range && *range < nearest) {
      const double z = origin.z() + *range * direction.z();
      if (z >= wall.z_min && z <= wall.z_max)
        nearest = *range;
    }
  }
  for (const Horizontal& horizontal : horizontals_) {
    if (direction.z() == 0.0)
      continue;
    const double range = (horizontal.z - origin.z()) / direction.z();
    if (range > 0.0 && range < nearest && inside(horizontal.outline, origin2 + range * direction2))
      nearest = range;
  }
  // Cylinders: |origin2 + r d2 - c|^2 = R^2, the nearer root whose height is on the pillar.
  const double a = direction2.squaredNorm();
  if (a > 0.0) {
    for (const Cylinder& cylinder : cylinders_) {
      const Eigen::Vector2d from_centre = origin2 - cylinder.centre;
      const double b = direction2.dot(from_centre);
      const double c = from_centre.squaredNorm() - cylinder.radius * cylinder.radius;
      const double discriminant = b * b - a * c;
      if (discriminant < 0.0)
        continue;
      const double root = std::sqrt(discriminant);
      for (const double range : {(-b - root) / a, (-b + root) / a}) {
        const double z = origin.z() + range * direction.z();
        if (range > 0.0 && z >= cylinder.z_min && z <= cylinder.z_max) {
          nearest = std::min(nearest, range);
          break;
        }
      }
    }
  }
  return std::isfinite(nearest) ? std::optional<double>(nearest) : std::nullopt;
}

double World3::distanceTo(const Eigen::Vector3d& point) const {
  // Every surface is a product of a planar shape and a height interval (or a plane of one height), so
  // the squared distance splits into a horizontal and a vertical part.
  const Eigen::Vector2d point2 = point.head<2>();
  double nearest = std::numeric_limits<double>::infinity();
  for (const Wall& wall : walls_) {
    nearest = std::min(nearest, std::hypot(distanceToSegment(point2, {wall.a, wall.b}),
                                           outside(point.z(), wall.z_min, wall.z_max)));
  }
  for (const Horizontal& horizontal : horizontals_) {
    double horizontal_distance = 0.0;
    if (!inside(horizontal.outline, point2)) {
      horizontal_distance = std::numeric_limits<double>::infinity();
      for (std::size_t i = 0; i < horizontal.outline.size(); ++i) {
        horizontal_distance = std::min(
            horizontal_distance,
            distanceToSegment(
                point2, {horizontal.outline[i], horizontal.outline[(i + 1) % horizontal.outline.size()]}));
      }
    }
    nearest = std::min(nearest, std::hypot(horizontal_distance, point.z() - horizontal.z));
  }
  for (const Cylinder& cylinder : cylinders_) {
    const double radial = std::abs((point2 - cylinder.centre).norm() - cylinder.radius);
    nearest = std::min(nearest, std::hypot(radial, outside(point.z(), cylinder.z_min, cylinder.z_max)));
  }
  return nearest;
}

World3 World3::hall() {
  World3 world("hall");
  world.addExtruded(World::hall(), 0.0, kHallHeight);
  const std::vector<Eigen::Vector2d> outline = World::hallOutline();
  world.addHorizontal(outline, 0.0);
  world.addHorizontal(outline, kHallHeight);
  world.addCylinder({-6.0, -1.5}, 0.3, 0.0, kHallHeight);
  world.addCylinder({-14.0, 2.5}, 0.25, 0.0, kHallHeight);
  world.addCylinder({1.0, 1.0}, 0.4, 0.0, kHallHeight);
  return world;
}

World3 World3::byName(const std::string& name) {
  if (name == "hall")
    return hall();
  throw std::invalid_argument("unknown world '" + name + "'; known: hall");
}

Pose3 RoughGroundTrajectory3::pose(double t) const {
  const Pose2 planar = planar_->pose(t);
  const auto wave = [t](double amplitude, double frequency) {
    return amplitude * std::sin(2.0 * M_PI * frequency * t);
  };
  return Pose3::fromXyzRpy(planar.x, planar.y, wave(ground_.z_amplitude, ground_.z_frequency),
                           wave(ground_.roll_amplitude, ground_.roll_frequency),
                           wave(ground_.pitch_amplitude, ground_.pitch_frequency), planar.yaw);
}

double SpinningLidarModel::azimuth(int column) const {
  const double step = 2.0 * M_PI / static_cast<double>(columns);
  return clockwise ? M_PI - column * step : M_PI + column * step;
}

Eigen::Vector3d SpinningLidarModel::direction(int ring, int column) const {
  const double elevation = ring_elevations.at(static_cast<std::size_t>(ring));
  const double a = azimuth(column);
  return {std::cos(elevation) * std::cos(a), std::cos(elevation) * std::sin(a), std::sin(elevation)};
}

SpinningLidarModel SpinningLidarModel::vlp16() {
  std::vector<double> elevations;
  for (int ring = 0; ring < 16; ++ring)
    elevations.push_back((-15.0 + 2.0 * ring) * M_PI / 180.0);
  return {"VLP16", elevations, 1800, 10.0, /*clockwise=*/true, /*organized=*/false, 0.03, 0.5, 100.0};
}

SpinningLidarModel SpinningLidarModel::os1_64() {
  std::vector<double> elevations;
  for (int ring = 0; ring < 64; ++ring)
    elevations.push_back((16.6 - 33.2 * ring / 63.0) * M_PI / 180.0);
  return {"OS1-64", elevations, 1024, 10.0, /*clockwise=*/false, /*organized=*/true, 0.03, 0.3, 120.0};
}

SpinningLidarModel SpinningLidarModel::byName(const std::string& name) {
  for (const SpinningLidarModel& model : {vlp16(), os1_64()}) {
    if (model.name == name)
      return model;
  }
  throw std::invalid_argument("unknown LIDAR model '" + name + "'; known: VLP16 OS1-64");
}

SimulatedCloud simulateSweep(const World3& world, const Trajectory3& trajectory, const Pose3& mount,
                             const SpinningLidarModel& model, double start_time, std::mt19937* noise) {
  SimulatedCloud cloud;
  cloud.rings = model.rings();
  cloud.columns = model.columns;
  cloud.organized = model.organized;
  cloud.start_time = start_time;
  cloud.end_time = start_time + (model.columns - 1) * model.columnPeriod();
  std::normal_distribution<double> range_noise(0.0, model.range_sigma);
  const std::size_t rings = model.ring_elevations.size();
  if (model.organized)
    cloud.points.resize(rings * static_cast<std::size_t>(model.columns));
  else
    cloud.points.reserve(rings * static_cast<std::size_t>(model.columns));
  for (int column = 0; column < model.columns; ++column) {
    const double time = start_time + column * model.columnPeriod();
    const Pose3 sensor = trajectory.pose(time).compose(mount);
    for (int ring = 0; ring < cloud.rings; ++ring) {
      const Eigen::Vector3d direction = model.direction(ring, column);
      const std::optional<double> hit = world.castRay(sensor.position, sensor.rotation * direction);
      SimulatedPoint point;
      point.time = time;
      point.ring = ring;
      point.column = column;
      point.is_return = hit && *hit >= model.range_min && *hit <= model.range_max;
      if (point.is_return) {
        point.range = noise ? *hit + range_noise(*noise) : *hit;
        point.position = point.range * direction;
        point.world_hit = sensor.apply(*hit * direction);
      } else {
        point.position = Eigen::Vector3d::Zero();
        point.world_hit = Eigen::Vector3d::Constant(kNaN);
      }
      if (model.organized)
        cloud.points[static_cast<std::size_t>(ring) * model.columns + column] = point;
      else if (point.is_return)
        cloud.points.push_back(point);
    }
  }
  return cloud;
}

std::vector<double> distancesToWorld(const World3& world, const Pose3& sensor_pose,
                                     const std::vector<Eigen::Vector3d>& points) {
  std::vector<double> distances;
  distances.reserve(points.size());
  for (const Eigen::Vector3d& point : points)
    distances.push_back(world.distanceTo(sensor_pose.apply(point)));
  return distances;
}

}  // namespace lidar_deskew::sim
