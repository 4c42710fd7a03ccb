#include "support/driver_clouds.h"

#include <sensor_msgs/PointField.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <cstring>

namespace lidar_deskew::test {
namespace {

using sensor_msgs::PointField;

PointField field(const std::string& name, std::uint32_t offset, std::uint8_t datatype) {
  PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = datatype;
  f.count = 1;
  return f;
}

}  // namespace

sensor_msgs::PointCloud2::Ptr cloudOf(const sensor_msgs::LaserScan& scan, Layout layout) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header = scan.header;
  const bool ouster = layout == Layout::kOuster;
  cloud->fields = {field("x", 0, PointField::FLOAT32), field("y", 4, PointField::FLOAT32),
                   field("z", 8, PointField::FLOAT32), field("intensity", 12, PointField::FLOAT32)};
  if (ouster)
    cloud->fields.push_back(field("range", 20, PointField::UINT32));
  cloud->fields.push_back(
      field(ouster ? "t" : "time", 16, ouster ? PointField::UINT32 : PointField::FLOAT32));
  cloud->point_step = 24;
  const std::size_t n = scan.ranges.size();
  const double last = (n - 1) * static_cast<double>(scan.time_increment);
  if (!ouster)
    cloud->header.stamp = scan.header.stamp + ros::Duration(last);  // the last packet
  std::vector<std::uint8_t> data;
  std::size_t points = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float r = scan.ranges[i];
    const bool hit = std::isfinite(r);
    if (!hit && !ouster)
      continue;  // dense: no-return points left out
    const double angle = scan.angle_min + i * static_cast<double>(scan.angle_increment);
    const float xyz[4] = {hit ? static_cast<float>(r * std::cos(angle)) : 0.0f,
                          hit ? static_cast<float>(r * std::sin(angle)) : 0.0f, 0.0f, 100.0f + i};
    const double offset = i * static_cast<double>(scan.time_increment);
    std::uint8_t point[24] = {};
    std::memcpy(point, xyz, sizeof xyz);
    if (ouster) {
      const auto t = static_cast<std::uint32_t>(std::llround(offset * 1e9));
      std::memcpy(point + 16, &t, sizeof t);
      const auto range_mm = static_cast<std::uint32_t>(hit ? std::llround(r * 1e3) : 0);
      std::memcpy(point + 20, &range_mm, sizeof range_mm);
    } else {
      const auto time = static_cast<float>(offset - last);
      std::memcpy(point + 16, &time, sizeof time);
    }
    data.insert(data.end(), point, point + 24);
    ++points;
  }
  cloud->width = static_cast<std::uint32_t>(points);
  cloud->height = 1;
  cloud->row_step = cloud->point_step * cloud->width;
  cloud->data = std::move(data);
  cloud->is_dense = !ouster;
  return cloud;
}

float floatAt(const sensor_msgs::PointCloud2& cloud, std::size_t i, std::uint32_t offset) {
  float value;
  std::memcpy(&value, &cloud.data[i * cloud.point_step + offset], sizeof value);
  return value;
}

std::vector<Xy> returnsOf(const sensor_msgs::PointCloud2& cloud) {
  std::vector<Xy> points;
  for (std::size_t i = 0; i < cloud.width; ++i) {
    const float x = floatAt(cloud, i, 0), y = floatAt(cloud, i, 4);
    if (x != 0.0f || y != 0.0f)
      points.push_back({x, y});
  }
  return points;
}

}  // namespace lidar_deskew::test
