#include "lidar_deskew/ros/bag_file.h"

#include <stdexcept>

namespace lidar_deskew::ros_adapter {

rosbag::Bag openBagForReading(const std::string& path) {
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& error) {
    throw std::runtime_error("cannot read " + path + ": " + error.what());
  }
  return bag;
}

}  // namespace lidar_deskew::ros_adapter
