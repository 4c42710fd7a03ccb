// Opening recorded bags, for deskew_bag and the evaluation tools alike.
#pragma once

#include <rosbag/bag.h>

#include <string>

namespace lidar_deskew::ros_adapter {

/// Opens a bag for reading; throws std::runtime_error naming the file when it cannot.
rosbag::Bag openBagForReading(const std::string& path);

}  // namespace lidar_deskew::ros_adapter
