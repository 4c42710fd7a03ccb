#include "lidar_deskew/ros/node_handle_params.h"

#include "lidar_deskew/core/types.h"

namespace lidar_deskew::ros_adapter {
namespace {

template <typename T>
bool getFromNodeHandle(const ros::NodeHandle& nh, const std::string& name, T& value, const char* expected) {
  if (!nh.hasParam(name))
    return false;
  if (!nh.getParam(name, value))
    throw core::InvalidInput(name, std::string("must be ") + expected);
  return true;
}

}  // namespace

bool NodeHandleParams::get(const std::string& name, std::string& value) const {
  return getFromNodeHandle(nh_, name, value, "a string");
}

bool NodeHandleParams::get(const std::string& name, double& value) const {
  if (!nh_.hasParam(name))
    return false;
  int integer = 0;
  if (nh_.getParam(name, value))
    return true;
  if (nh_.getParam(name, integer)) {  // YAML "1" is an int; accept it for a double parameter
    value = integer;
    return true;
  }
  throw core::InvalidInput(name, "must be a number");
}

bool NodeHandleParams::get(const std::string& name, int& value) const {
  return getFromNodeHandle(nh_, name, value, "an integer");
}

bool NodeHandleParams::get(const std::string& name, bool& value) const {
  return getFromNodeHandle(nh_, name, value, "true or false");
}

}  // namespace lidar_deskew::ros_adapter
