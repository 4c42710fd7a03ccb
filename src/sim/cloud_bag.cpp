#include "lidar_deskew/sim/cloud_bag.h"

#include <rosbag/bag.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/sim_bag.h"

namespace lidar_deskew::sim {
namespace {

using ros_adapter::toRosTime;
using sensor_msgs::PointField;

constexpr float kIntensity = 100.0f;

struct Field {
  const char* name;
  std::uint32_t offset;
  std::uint8_t datatype;
};

/// The fields beyond x, y, z and the point step of each convention (cloud_bag.h's table).
struct Layout {
  std::vector<Field> fields;
  std::uint32_t point_step;
};

/// The base pose a wheeled robot's odometry reports on 3D ground: x, y and yaw from `odometry`, z, roll
/// and pitch as `truth` (whose planar part is `planar_truth`). Bit for bit `truth` when `odometry` is
/// `planar_truth`.
Pose3 withPlanarOdometry(const Pose3& truth, const Pose2& planar_truth, const Pose2& odometry) {
  Pose3 pose = truth;
  pose.position.x() += odometry.x - planar_truth.x;
  pose.position.y() += odometry.y - planar_truth.y;
  const double turn = odometry.yaw - planar_truth.yaw;  // about the fixed frame's z, before the tilt
  if (turn != 0.0) {
    Eigen::Matrix3d about_z;
    about_z << std::cos(turn), -std::sin(turn), 0.0, std::sin(turn), std::cos(turn), 0.0, 0.0, 0.0, 1.0;
    pose.rotation = about_z * truth.rotation;
  }
  return pose;
}

Layout layoutOf(CloudConvention convention) {
  switch (convention) {
    case CloudConvention::kOuster:
      return {{{"intensity", 16, PointField::FLOAT32},
               {"t", 20, PointField::UINT32},
               {"reflectivity", 24, PointField::UINT16},
               {"ring", 26, PointField::UINT16},
               {"ambient", 28, PointField::UINT16},
               {"range", 32, PointField::UINT32}},
              48};
    case CloudConvention::kVelodyneFirst:
    case CloudConvention::kVelodyneLast:
      return {{{"intensity", 12, PointField::FLOAT32},
               {"ring", 16, PointField::UINT16},
               {"time", 18, PointField::FLOAT32}},
              22};
    case CloudConvention::kHesai:
      return {{{"intensity", 16, PointField::FLOAT32},
               {"timestamp", 24, PointField::FLOAT64},
               {"ring", 32, PointField::UINT16}},
              48};
    case CloudConvention::kRoboSense:
      return {{{"intensity", 16, PointField::FLOAT32},
               {"ring", 20, PointField::UINT16},
               {"timestamp", 24, PointField::FLOAT64}},
              32};
    case CloudConvention::kLivox2:
      return {{{"intensity", 12, PointField::FLOAT32},
               {"tag", 16, PointField::UINT8},
               {"line", 17, PointField::UINT8},
               {"timestamp", 18, PointField::FLOAT64}},
              26};
    case CloudConvention::kAutoware:
      return {{{"intensity", 12, PointField::FLOAT32},
               {"ring", 16, PointField::UINT16},
               {"time_stamp", 20, PointField::UINT32}},
              24};
    case CloudConvention::kLivoxCustom:
      return {{{"reflectivity", 12, PointField::FLOAT32},
               {"tag", 16, PointField::UINT8},
               {"line", 17, PointField::UINT8},
               {"offset_time", 20, PointField::UINT32}},
              24};
    case CloudConvention::kLaserGeometry:
      return {{{"intensity", 12, PointField::FLOAT32}, {"stamps", 16, PointField::FLOAT32}}, 20};
    case CloudConvention::kNoTime:
      return {{{"intensity", 16, PointField::FLOAT32}, {"ring", 20, PointField::UINT16}}, 32};
  }
  throw std::invalid_argument("unknown cloud convention");
}

template <typename T>
void put(std::uint8_t* point, std::uint32_t offset, T value) {
  std::memcpy(point + offset, &value, sizeof(T));
}

/// Absolute bag time [ns] of a time t [s] on the simulation clock.
core::TimeNs bagTime(core::TimeNs epoch, double t) {
  return epoch + core::secondsToNs(t);
}

}  // namespace

geometry_msgs::TransformStamped stamped(const std::string& parent, const std::string& child,
                                        core::TimeNs time, const Pose3& pose) {
  geometry_msgs::TransformStamped transform;
  transform.header.frame_id = parent;
  transform.header.stamp = toRosTime(time);
  transform.child_frame_id = child;
  transform.transform.translation.x = pose.position.x();
  transform.transform.translation.y = pose.position.y();
  transform.transform.translation.z = pose.position.z();
  const Eigen::Quaterniond rotation = pose.quaternion();
  transform.transform.rotation.x = rotation.x();
  transform.transform.rotation.y = rotation.y();
  transform.transform.rotation.z = rotation.z();
  transform.transform.rotation.w = rotation.w();
  return transform;
}

const std::vector<CloudConvention>& allCloudConventions() {
  static const std::vector<CloudConvention> conventions = {
      CloudConvention::kOuster,   CloudConvention::kVelodyneFirst, CloudConvention::kVelodyneLast,
      CloudConvention::kHesai,    CloudConvention::kRoboSense,     CloudConvention::kLivox2,
      CloudConvention::kAutoware, CloudConvention::kLivoxCustom,   CloudConvention::kLaserGeometry};
  return conventions;
}

std::string cloudConventionName(CloudConvention convention) {
  switch (convention) {
    case CloudConvention::kOuster:
      return "ouster";
    case CloudConvention::kVelodyneFirst:
      return "velodyne_first";
    case CloudConvention::kVelodyneLast:
      return "velodyne_last";
    case CloudConvention::kHesai:
      return "hesai";
    case CloudConvention::kRoboSense:
      return "robosense";
    case CloudConvention::kLivox2:
      return "livox2";
    case CloudConvention::kAutoware:
      return "autoware";
    case CloudConvention::kLivoxCustom:
      return "livox_custom";
    case CloudConvention::kLaserGeometry:
      return "laser_geometry";
    case CloudConvention::kNoTime:
      return "no_time";
  }
  throw std::invalid_argument("unknown cloud convention");
}

std::vector<std::string> cloudConventionNames() {
  std::vector<std::string> names;
  for (const CloudConvention convention : allCloudConventions())
    names.push_back(cloudConventionName(convention));
  names.push_back(cloudConventionName(CloudConvention::kNoTime));
  return names;
}

CloudConvention cloudConventionFromName(const std::string& name) {
  if (name == cloudConventionName(CloudConvention::kNoTime))
    return CloudConvention::kNoTime;
  std::string names;
  for (const CloudConvention convention : allCloudConventions()) {
    if (cloudConventionName(convention) == name)
      return convention;
  }
  for (const std::string& known : cloudConventionNames())
    names += " " + known;
  throw std::invalid_argument("unknown cloud convention '" + name + "'; known:" + names);
}

std::string cloudTimeField(CloudConvention convention) {
  for (const Field& field : layoutOf(convention).fields) {
    const std::string name = field.name;
    if (name == "t" || name == "time" || name == "timestamp" || name == "time_stamp" ||
        name == "offset_time" || name == "stamps")
      return name;
  }
  throw std::invalid_argument("cloud convention without a time field");
}

sensor_msgs::PointCloud2 toPointCloud2(const SimulatedCloud& sweep, CloudConvention convention,
                                       core::TimeNs epoch, const std::string& frame_id, std::uint32_t seq) {
  const bool organized = isOrganized(convention);
  if (sweep.organized != organized) {
    throw std::invalid_argument("toPointCloud2: convention " + cloudConventionName(convention) + " needs " +
                                (organized ? "an organized" : "a dense") + " sweep");
  }
  if (sweep.points.empty())
    throw std::invalid_argument("toPointCloud2: an empty sweep has no first point to stamp with");
  const Layout layout = layoutOf(convention);
  sensor_msgs::PointCloud2 cloud;
  cloud.header.seq = seq;
  cloud.header.frame_id = frame_id;
  // The stamp on the simulation clock [s]: sweep start, first or last point; on whole nanoseconds,
  // rounded down (start, first) or up (last), so that relative times never change sign.
  const bool stamp_at_last =
      convention == CloudConvention::kVelodyneLast || convention == CloudConvention::kRoboSense;
  double stamp_time = stamp_at_last ? sweep.points.back().time : sweep.points.front().time;
  if (convention == CloudConvention::kOuster)
    stamp_time = sweep.start_time;
  const double stamp_ns = stamp_time * 1e9;
  const core::TimeNs stamp =
      epoch + static_cast<core::TimeNs>(stamp_at_last ? std::ceil(stamp_ns) : std::floor(stamp_ns));
  cloud.header.stamp = toRosTime(stamp);
  const double stamp_on_clock = core::nsToSeconds(stamp - epoch);  // exactly the stamp written

  for (const char* axis : {"x", "y", "z"}) {
    PointField field;
    field.name = axis;
    field.offset = static_cast<std::uint32_t>(4 * cloud.fields.size());
    field.datatype = PointField::FLOAT32;
    field.count = 1;
    cloud.fields.push_back(field);
  }
  for (const Field& entry : layout.fields) {
    PointField field;
    field.name = entry.name;
    field.offset = entry.offset;
    field.datatype = entry.datatype;
    field.count = 1;
    cloud.fields.push_back(field);
  }
  cloud.height = organized ? static_cast<std::uint32_t>(sweep.rings) : 1;
  cloud.width = static_cast<std::uint32_t>(sweep.points.size()) / cloud.height;
  cloud.is_bigendian = false;
  cloud.point_step = layout.point_step;
  cloud.row_step = cloud.point_step * cloud.width;
  cloud.is_dense = !organized;  // Ouster's zeros are no NaNs, but ouster-ros says false: so do we
  cloud.data.assign(static_cast<std::size_t>(cloud.row_step) * cloud.height, 0);

  const core::TimeNs epoch_seconds = epoch / 1'000'000'000;
  const double epoch_fraction = core::nsToSeconds(epoch % 1'000'000'000);
  for (std::size_t i = 0; i < sweep.points.size(); ++i) {
    const SimulatedPoint& point = sweep.points[i];
    std::uint8_t* out = cloud.data.data() + i * cloud.point_step;
    put(out, 0, static_cast<float>(point.position.x()));
    put(out, 4, static_cast<float>(point.position.y()));
    put(out, 8, static_cast<float>(point.position.z()));
    const double relative = point.time - stamp_on_clock;  // [s]
    const auto relative_ns = static_cast<std::uint32_t>(std::llround(relative * 1e9));
    const float intensity = point.is_return ? kIntensity : 0.0f;
    const auto ring = static_cast<std::uint16_t>(point.ring);
    for (const Field& field : layout.fields) {
      const std::string name = field.name;
      if (name == "intensity" || name == "reflectivity") {
        if (field.datatype == PointField::FLOAT32)
          put(out, field.offset, intensity);
        else
          put(out, field.offset, static_cast<std::uint16_t>(intensity));
      } else if (name == "ring" || name == "line") {
        if (field.datatype == PointField::UINT16)
          put(out, field.offset, ring);
        else
          put(out, field.offset, static_cast<std::uint8_t>(point.ring));
      } else if (name == "range") {  // Ouster: [mm]
        put(out, field.offset, static_cast<std::uint32_t>(std::llround(point.range * 1e3)));
      } else if (name == "t" || name == "time_stamp" || name == "offset_time") {
        put(out, field.offset, relative_ns);
      } else if (name == "time" || name == "stamps") {
        put(out, field.offset, static_cast<float>(relative));
      } else if (name == "timestamp" && convention == CloudConvention::kLivox2) {  // absolute [ns]
        put(out, field.offset, static_cast<double>(bagTime(epoch, point.time)));
      } else if (name == "timestamp") {  // absolute [s]
        put(out, field.offset, static_cast<double>(epoch_seconds) + (epoch_fraction + point.time));
      }
      // tag, ambient: 0
    }
  }
  return cloud;
}

void writeCloudBag(const CloudScenario& scenario, const CloudBagOptions& options, const std::string& bag_path,
                   const std::string& truth_path) {
  if (!(options.tf_rate > 0.0))
    throw std::invalid_argument("writeCloudBag: tf_rate must be > 0 Hz");
  CloudScenario run = scenario;
  if (options.duration > 0.0)
    run.duration = options.duration;
  run.lidar.organized = isOrganized(options.convention);
  const std::shared_ptr<const Trajectory3> trajectory = run.trajectory();
  const World3 world = World3::hall();
  const std::vector<double> sweep_starts = run.sweepStartTimes();
  if (sweep_starts.empty())
    throw std::invalid_argument("writeCloudBag: the duration holds no sweep");
  const core::TimeNs epoch = options.epoch;
  const auto at = [&](double t) { return bagTime(epoch, t); };

  if (!(options.tf_margin >= 0.0) || !std::isfinite(options.tf_margin))
    throw std::invalid_argument("writeCloudBag: tf_margin must be finite and >= 0 s");
  const double tf_begin = sweep_starts.front() - options.tf_margin;
  const double tf_end = sweep_starts.back() + run.lidar.sweepPeriod() + options.tf_margin;
  const long tf_samples = std::lround(std::floor((tf_end - tf_begin) * options.tf_rate + 1e-9));
  // What the wheels measure of the planar motion, in the order a recorder writes it (throws for a bad
  // odometry option).
  const PiecewiseTrajectory planar(run.start, run.pieces);
  const std::vector<OdometrySample> odometry =
      recordOdometry(planar, tf_begin, tf_samples, tf_end, options.tf_rate, options.odom_noise,
                     options.odom_noise_seed, options.odom_yaw_scale, options.odom_timing);

  rosbag::Bag bag(bag_path, rosbag::bagmode::Write);

  // The mount first, at the earliest odometry stamp (tf_begin unless the stamps jitter).
  double static_time = tf_begin;
  for (const OdometrySample& sample : odometry)
    static_time = std::min(static_time, sample.stamp);
  tf2_msgs::TFMessage static_transforms;
  static_transforms.transforms.push_back(
      stamped(options.base_frame, options.lidar_frame, at(static_time), run.mount));
  writeTfStatic(bag, toRosTime(at(static_time)), static_transforms);

  const auto writeTf = [&](const OdometrySample& sample) {
    const Pose3 pose =
        withPlanarOdometry(trajectory->pose(sample.time), planar.pose(sample.time), sample.pose);
    tf2_msgs::TFMessage transforms;
    transforms.transforms.push_back(stamped(options.fixed_frame, options.base_frame, at(sample.stamp), pose));
    bag.write("/tf", toRosTime(at(sample.record)), transforms);
  };

  // Written in time order, as a recorder does.
  std::mt19937 rng(options.seed);
  std::size_t next_tf = 0;
  for (std::size_t k = 0; k < sweep_starts.size(); ++k) {
    const SimulatedCloud sweep = simulateSweep(world, *trajectory, run.mount, run.lidar, sweep_starts[k],
                                               options.noise ? &rng : nullptr);
    const double record_time = sweep.end_time + options.latency;
    while (next_tf < odometry.size() && odometry[next_tf].record <= record_time)
      writeTf(odometry[next_tf++]);
    bag.write(
        options.cloud_topic, toRosTime(at(record_time)),
        toPointCloud2(sweep, options.convention, epoch, options.lidar_frame, static_cast<std::uint32_t>(k)));
  }
  while (next_tf < odometry.size())
    writeTf(odometry[next_tf++]);
  bag.close();

  CloudTruth truth;
  truth.scenario = run.name;
  truth.world = world.name();
  truth.sensor = run.lidar.name;
  truth.convention = cloudConventionName(options.convention);
  truth.epoch = epoch;
  truth.range_sigma = options.noise ? run.lidar.range_sigma : 0.0;
  truth.mount = run.mount;
  truth.start = run.start;
  truth.pieces = run.pieces;
  truth.rough = run.rough;
  truth.sweep_start_times = sweep_starts;
  truth.odom_noise = options.odom_noise;
  truth.odom_noise_seed = options.odom_noise_seed;
  truth.odom_yaw_scale = options.odom_yaw_scale;
  truth.odom_timing = options.odom_timing;
  writeCloudTruth(truth, truth_path);
}

}  // namespace lidar_deskew::sim
