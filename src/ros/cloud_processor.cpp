#include "lidar_deskew/ros/cloud_processor.h"

#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"

namespace lidar_deskew::ros_adapter {
namespace {

using sensor_msgs::PointField;

/// The x, y or z field: float32 or float64.
const PointField& coordinateField(const sensor_msgs::PointCloud2& cloud, const std::string& name) {
  for (const PointField& field : cloud.fields) {
    if (field.name != name)
      continue;
    if (field.datatype != PointField::FLOAT32 && field.datatype != PointField::FLOAT64)
      throw core::InvalidInput("fields", name + " is neither float32 nor float64");
    return field;
  }
  throw core::InvalidInput("fields", "no " + name + " field");
}

void writeNumber(std::uint8_t* at, std::uint8_t datatype, double value) {
  const auto write = [at](auto typed) { std::memcpy(at, &typed, sizeof typed); };
  switch (datatype) {
    case PointField::INT8:
      return write(static_cast<std::int8_t>(value));
    case PointField::UINT8:
      return write(static_cast<std::uint8_t>(value));
    case PointField::INT16:
      return write(static_cast<std::int16_t>(value));
    case PointField::UINT16:
      return write(static_cast<std::uint16_t>(value));
    case PointField::INT32:
      return write(static_cast<std::int32_t>(value));
    case PointField::UINT32:
      return write(static_cast<std::uint32_t>(value));
    case PointField::FLOAT32:
      return write(static_cast<float>(value));
    case PointField::FLOAT64:
      return write(value);
  }
}

}  // namespace

CloudProcessor::CloudProcessor(const DeskewParams& params)
    : params_(params), time_config_(params.cloud_time), deskewer_(params.deskew) {
  time_config_.max_sweep_duration = params.timing.max_sweep_duration;
  time_config_.validate();
  // The planar scan's band and grid, pairwise (each bound alone is checked with the parameters).
  if (params.cloud_scan.height_max < params.cloud_scan.height_min)
    throw core::InvalidInput("scan_height_max", "must not be below scan_height_min");
  if (params.cloud_scan.angle_max <= params.cloud_scan.angle_min)
    throw core::InvalidInput("scan_angle_max", "must be above scan_angle_min");
}

PreparedCloud CloudProcessor::prepare(const sensor_msgs::PointCloud2::ConstPtr& message) const {
  const sensor_msgs::PointCloud2& cloud = *message;
  if (cloud.header.frame_id.empty())
    throw core::InvalidInput("header.frame_id", "is empty");
  checkCloudLayout(cloud);
  const PointField& x = coordinateField(cloud, "x");
  const PointField& y = coordinateField(cloud, "y");
  const PointField& z = coordinateField(cloud, "z");
  PreparedCloud prepared;
  prepared.message = message;
  // An organized cloud is taken column by column: the points of one column share a firing time, and
  // the core then maps each column's points with one transform. Entry j of points and times is the
  // cloud's point order[j].
  const std::size_t count = static_cast<std::size_t>(cloud.width) * cloud.height;
  const bool by_column = cloud.height > 1;
  const auto entryOf = [&](std::size_t i) {
    return by_column ? (i % cloud.width) * cloud.height + i / cloud.width : i;
  };
  if (by_column)
    prepared.order.resize(count);
  prepared.points.resize(count);
  prepared.times.resize(count);
  // Returns: finite coordinates, not exactly the origin (range 0: "no return" for Ouster and others).
  // Only their times count; a no-return point may carry any time, or none.
  std::vector<bool> is_return(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t j = entryOf(i);
    if (by_column)
      prepared.order[j] = static_cast<std::uint32_t>(i);
    const std::uint8_t* point = &cloud.data[pointOffset(cloud, i)];
    Eigen::Vector3d& p = prepared.points[j];
    p = {readNumber(point + x.offset, x.datatype), readNumber(point + y.offset, y.datatype),
         readNumber(point + z.offset, z.datatype)};
    is_return[i] = p.allFinite() && !p.isZero(0.0);
    if (!is_return[i])
      p.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
  prepared.time_field = findTimeField(cloud, time_config_, &is_return);
  std::vector<core::TimeNs> times;
  pointTimes(cloud, prepared.time_field, times, &is_return);
  core::TimeNs first = std::numeric_limits<core::TimeNs>::max();
  core::TimeNs last = std::numeric_limits<core::TimeNs>::min();
  for (std::size_t i = 0; i < count; ++i) {
    prepared.times[entryOf(i)] = times[i];
    if (!is_return[i])
      continue;
    ++prepared.returns;
    first = std::min(first, times[i]);
    last = std::max(last, times[i]);
  }
  if (prepared.returns == 0)
    first = last = toNs(cloud.header.stamp);
  if (core::nsToSeconds(last - first) > params_.timing.max_sweep_duration) {
    throw core::InvalidInput("time field", prepared.time_field.name + " spans " +
                                               formatNumber(core::nsToSeconds(last - first)) +
                                               " s, more than max_sweep_duration");
  }
  constexpr core::TimeNs kLatestTime = (static_cast<core::TimeNs>(1) << 32) * 1'000'000'000 - 100'000'000'000;
  if (first < 0 || last > kLatestTime)
    throw core::InvalidInput("time field", "puts the sweep outside the range of ROS time");
  prepared.first = first;
  prepared.last = last;
  return prepared;
}

CloudOutputs CloudProcessor::correct(const PreparedCloud& prepared, const mrpt::poses::CPose3D& mount,
                                     const core::MotionSource& motion) {
  checkTfGaps(params_.max_tf_gap, motion, prepared.first, prepared.last);
  const std::size_t count = prepared.points.size();
  offsets_.resize(count);
  for (std::size_t i = 0; i < count; ++i)
    offsets_[i] = core::nsToSeconds(prepared.times[i] - prepared.first);
  const core::TimeNs reference = deskewer_.deskewPoints(prepared.points, offsets_, prepared.first, mount,
                                                        motion, corrected_, corrected_offsets_, kept_);

  const sensor_msgs::PointCloud2& input = *prepared.message;
  auto output = boost::make_shared<sensor_msgs::PointCloud2>(input);
  output->header.stamp = toRosTime(reference);
  const PointField& x = coordinateField(input, "x");
  const PointField& y = coordinateField(input, "y");
  const PointField& z = coordinateField(input, "z");
  const CloudTimeField& time = prepared.time_field;
  // The time each corrected position holds: the reference, 0 from the new stamp.
  // (absolute: whole units and the fraction apart, as the drivers write them)
  double time_value = 0.0;
  if (time.absolute) {
    const auto unit_ns = static_cast<core::TimeNs>(std::llround(time.unit * 1e9));
    time_value = static_cast<double>(reference / unit_ns) +
                 static_cast<double>(reference % unit_ns) / static_cast<double>(unit_ns);
  }
  for (std::size_t k = 0; k < kept_.size(); ++k) {
    std::uint8_t* point =
        &output->data[pointOffset(input, prepared.order.empty() ? kept_[k] : prepared.order[kept_[k]])];
    writeNumber(point + x.offset, x.datatype, corrected_[k].x());
    writeNumber(point + y.offset, y.datatype, corrected_[k].y());
    writeNumber(point + z.offset, z.datatype, corrected_[k].z());
    writeNumber(point + time.offset, time.datatype, time_value);
  }
  CloudOutputs outputs;
  outputs.cloud = output;
  if (params_.cloud_scan.enabled)
    outputs.scan = planarScan(corrected_, output->header);
  return outputs;
}

CloudOutputs CloudProcessor::passThrough(const PreparedCloud& prepared) const {
  CloudOutputs outputs;
  outputs.cloud = prepared.message;
  if (params_.cloud_scan.enabled)
    outputs.scan = planarScan(prepared.points, prepared.message->header);  // the raw points
  return outputs;
}

sensor_msgs::LaserScan::ConstPtr CloudProcessor::planarScan(const std::vector<Eigen::Vector3d>& points,
                                                            const std_msgs::Header& header) const {
  const DeskewParams::CloudScan& band = params_.cloud_scan;
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  scan->header = header;
  scan->angle_min = static_cast<float>(band.angle_min);
  scan->angle_increment = static_cast<float>(band.angle_increment);
  const auto bins =
      static_cast<std::size_t>(std::floor((band.angle_max - band.angle_min) / band.angle_increment)) + 1;
  scan->angle_max = static_cast<float>(band.angle_min + (bins - 1) * band.angle_increment);
  scan->time_increment = 0.0f;  // every point refers to the stamp
  scan->scan_time = 0.0f;
  scan->range_min = 0.0f;
  scan->range_max = static_cast<float>(band.range_max);
  scan->ranges.assign(bins, std::numeric_limits<float>::infinity());
  for (const Eigen::Vector3d& point : points) {
    if (!point.allFinite() || point.z() < band.height_min || point.z() > band.height_max)
      continue;
    const double range = std::hypot(point.x(), point.y());
    if (range > band.range_max || range == 0.0)
      continue;
    // The nearest point on each bin's ray (pointcloud_to_laserscan's rule, after the correction).
    const double bin = std::round((std::atan2(point.y(), point.x()) - band.angle_min) / band.angle_increment);
    if (bin < 0.0 || bin >= static_cast<double>(bins))
      continue;
    float& kept = scan->ranges[static_cast<std::size_t>(bin)];
    kept = std::min(kept, static_cast<float>(range));
  }
  return scan;
}

}  // namespace lidar_deskew::ros_adapter
