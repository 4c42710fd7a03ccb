// Test support: a simulated LaserScan written as drivers write PointCloud2s (Ouster's organized layout
// with zeros for no return, uint32 ns offsets and uint32 mm ranges; Velodyne's dense layout stamped at the
// last packet with negative float32 seconds).
#pragma once

#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>

#include <vector>

namespace lidar_deskew::test {

enum class Layout { kOuster, kVelodyneLast };

struct Xy {
  double x, y;
};

/// The scan as a driver's cloud: x y z float32 at 0, intensity float32 at 12 (100 + the beam's index),
/// the time field at 16, point_step 24; Ouster's also range uint32 [mm] at 20 (the beam's range, 0 for no
/// return), listed before the time field.
sensor_msgs::PointCloud2::Ptr cloudOf(const sensor_msgs::LaserScan& scan, Layout layout);

/// The float32 at `offset` of point i (height 1).
float floatAt(const sensor_msgs::PointCloud2& cloud, std::size_t i, std::uint32_t offset);

/// The returns (x, y not both 0) of a cloud made by cloudOf, or its corrected copy.
std::vector<Xy> returnsOf(const sensor_msgs::PointCloud2& cloud);

}  // namespace lidar_deskew::test
