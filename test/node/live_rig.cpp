#include "live_rig.h"

#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::test {

LiveRig::LiveRig(const sim::LidarModel& lidar, const std::string& ns)
    : LiveRig(lidar, ns, {{1.0, 6.0, 0.0, 5.0}}) {}  // an arc for ever (the last piece goes on)

LiveRig::LiveRig(const sim::LidarModel& lidar, const std::string& ns, std::vector<sim::MotionPiece> pieces)
    : world(sim::World::demoRoom()),
      trajectory({-2.0, -1.0, 0.3}, std::move(pieces)),
      mount{0.25, 0.05, 0.1},
      model(lidar),
      nh_(ns),
      diagnostics_name_(ns.empty() ? "deskew" : ns + "/") {
  // Whole milliseconds: stamps then land exactly on the tf sample grid.
  epoch_.fromNSec(ros::Time::now().toNSec() / 1'000'000 * 1'000'000);
  tf_publisher_ = nh_.advertise<tf2_msgs::TFMessage>("/tf", 100);
  tf_static_publisher_ = nh_.advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
  scan_publisher = nh_.advertise<sensor_msgs::LaserScan>("scan", 10);
}

void LiveRig::subscribeOutputs() {
  scan_subscriber_ = nh_.subscribe<sensor_msgs::LaserScan>(
      "scan_deskewed", 20, [this](const sensor_msgs::LaserScan::ConstPtr& scan) {
        scans_.push_back(scan);
        if (scans_.size() > history_)
          scans_.pop_front();
      });
  cloud_subscriber_ = nh_.subscribe<sensor_msgs::PointCloud2>(
      "scan_deskewed_points", 20, [this](const sensor_msgs::PointCloud2::ConstPtr& cloud) {
        clouds_.push_back(cloud);
        if (clouds_.size() > history_)
          clouds_.pop_front();
      });
  diagnostics_subscriber_ = nh_.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 20, [this](const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
        for (const auto& status : array->status) {
          if (status.name.find(diagnostics_name_) == std::string::npos)
            continue;
          ++diagnostics_received_;
          statuses_[status.name] = {status.level, status.message};
          for (const auto& value : status.values)
            diagnostics_[value.key] = value.value;
        }
      });
}

std::vector<std::string> LiveRig::statusNames() const {
  std::vector<std::string> names;
  for (const auto& [name, status] : statuses_)
    names.push_back(name);
  return names;
}

bool testFlag(const std::string& name) {
  bool value = false;
  ros::NodeHandle("~").getParam(name, value);
  return value;
}

bool LiveRig::status(const std::string& suffix, int& level, std::string& message) const {
  for (const auto& [name, status] : statuses_) {
    if (name.size() >= suffix.size() &&
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      std::tie(level, message) = status;
      return true;
    }
  }
  return false;
}

bool LiveRig::connect() {
  subscribeOutputs();
  // Both ways: the deskew reads `scan`, and this rig's output subscriptions are connected (when the
  // deskew already had other subscribers, it was reading `scan` before this rig subscribed).
  if (!waitFor(
          [&] {
            return scan_publisher.getNumSubscribers() == 1 && scan_subscriber_.getNumPublishers() > 0 &&
                   cloud_subscriber_.getNumPublishers() > 0;
          },
          5.0))
    return false;
  publishMount();
  return true;
}

void LiveRig::unsubscribeOutputs() {
  scan_subscriber_.shutdown();
  cloud_subscriber_.shutdown();
}

void LiveRig::publishMount() {
  // The deskew listens to tf from its start; wait until it is connected to this process's publishers.
  waitFor(
      [&] { return tf_publisher_.getNumSubscribers() > 0 && tf_static_publisher_.getNumSubscribers() > 0; },
      10.0);
  setMount(mount);
}

void LiveRig::setMount(const sim::Pose2& new_mount, double t) {
  mount = new_mount;
  // All static links in one latched message: moving -> base, base -> (plate ->) laser.
  tf2_msgs::TFMessage message;
  message.transforms = staticLinks(tree_, mount, stampOf(t));
  tf_static_publisher_.publish(message);
}

void LiveRig::publishStatic(const std::string& parent, const std::string& child, const sim::Pose2& pose) {
  tf2_msgs::TFMessage message;
  message.transforms.push_back(stamped(parent, child, epoch_, pose));
  tf_static_publisher_.publish(message);
}

void LiveRig::useOdometryYawScale(double yaw_scale, double until) {
  odometry_ = std::make_unique<sim::NoisyOdometry>(trajectory, -2.0, until, 0.0, 1, yaw_scale);
}

void LiveRig::publishTfUntil(double t) {
  if (tf_until_ < 0.0)  // the first call: a second of history is enough (and keeps time from going back)
    tf_until_ = std::max(tf_until_, t - 1.0);
  for (double sample = std::round(tf_until_ / 0.02) * 0.02 + 0.02; sample <= t + 1e-9; sample += 0.02) {
    tf2_msgs::TFMessage message;
    message.transforms.push_back(stamped(tree_.fixed, tree_.moving, stampOf(sample),
                                         odometry_ ? odometry_->pose(sample) : trajectory.pose(sample)));
    tf_publisher_.publish(message);
    tf_until_ = sample;
  }
}

sim::SimulatedScan LiveRig::publishScan(double t,
                                        const std::function<void(sensor_msgs::LaserScan&)>& modify) {
  const sim::SimulatedScan simulated = sim::simulateScan(world, trajectory, mount, model, epoch_.toNSec(), t);
  sensor_msgs::LaserScan scan = scanMessage(simulated, tree_.laser);
  if (modify)
    modify(scan);
  scan_publisher.publish(scan);
  return simulated;
}

bool LiveRig::waitFor(const std::function<bool()>& done, double timeout) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (!done() && ros::WallTime::now() < end && ros::ok()) {
    ros::spinOnce();
    ros::WallDuration(0.002).sleep();
  }
  return done();
}

bool LiveRig::waitForOutputs(const ros::Time& stamp, double timeout, sensor_msgs::LaserScan::ConstPtr& scan,
                             sensor_msgs::PointCloud2::ConstPtr& cloud, double tolerance) {
  scan.reset();
  cloud.reset();
  const auto near = [&](const ros::Time& other) { return std::abs((other - stamp).toSec()) <= tolerance; };
  waitFor(
      [&] {
        for (const auto& s : scans_) {
          if (near(s->header.stamp))
            scan = s;
        }
        for (const auto& c : clouds_) {
          if (near(c->header.stamp))
            cloud = c;
        }
        return scan && cloud;
      },
      timeout);
  return scan && cloud;
}

std::size_t LiveRig::outputCount(const ros::Time& from, const ros::Time& to) const {
  std::size_t count = 0;
  for (const auto& scan : scans_)
    count += scan->header.stamp >= from && scan->header.stamp <= to;
  return count;
}

std::string LiveRig::diagnostic(const std::string& key) const {
  const auto it = diagnostics_.find(key);
  return it == diagnostics_.end() ? std::string() : it->second;
}

double LiveRig::diagnosticNumber(const std::string& key) const {
  const std::string text = diagnostic(key);
  return text.empty() ? -1.0 : std::stod(text);
}

ros::Time LiveRig::stampOf(double t) const {
  return ros_adapter::toRosTime(epoch_.toNSec() + core::secondsToNs(t));
}
double LiveRig::secondsOf(const ros::Time& stamp) const {
  return (stamp - epoch_).toSec();
}

std::vector<double> cloudDistances(const LiveRig& rig, const sensor_msgs::PointCloud2& cloud) {
  return cloudDistances(rig, cloud, rig.mount);
}

std::vector<double> cloudDistances(const LiveRig& rig, const sensor_msgs::PointCloud2& cloud,
                                   const sim::Pose2& mount) {
  const sim::Pose2 laser = rig.trajectory.pose(rig.secondsOf(cloud.header.stamp)).compose(mount);
  std::vector<double> distances;
  for (sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"); x != x.end(); ++x, ++y) {
    distances.push_back(rig.world.distanceTo(laser.apply({*x, *y})));
  }
  return distances;
}

std::vector<double> scanDistances(const LiveRig& rig, const sensor_msgs::LaserScan& scan) {
  const sim::Pose2 laser = rig.trajectory.pose(rig.secondsOf(scan.header.stamp)).compose(rig.mount);
  std::vector<double> distances;
  for (std::size_t b = 0; b < scan.ranges.size(); ++b) {
    const double range = scan.ranges[b];
    if (!std::isfinite(range) || range < scan.range_min || range > scan.range_max)
      continue;
    const double angle = scan.angle_min + b * static_cast<double>(scan.angle_increment);
    distances.push_back(
        rig.world.distanceTo(laser.apply(range * Eigen::Vector2d(std::cos(angle), std::sin(angle)))));
  }
  return distances;
}

std::vector<double> rawDistances(const LiveRig& rig, const sim::SimulatedScan& input, double start) {
  const sim::Pose2 laser = rig.trajectory.pose(start).compose(rig.mount);
  std::vector<double> distances;
  for (std::size_t i = 0; i < input.scan.ranges.size(); ++i) {
    const double angle = input.scan.angle_min + i * static_cast<double>(input.scan.angle_increment);
    distances.push_back(rig.world.distanceTo(
        laser.apply(input.scan.ranges[i] * Eigen::Vector2d(std::cos(angle), std::sin(angle)))));
  }
  return distances;
}

}  // namespace lidar_deskew::test
