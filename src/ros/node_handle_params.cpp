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
  // roscpp would round a YAML 2.5 to 2: refuse anything but an integer.
  XmlRpc::XmlRpcValue raw;
  if (!nh_.getParam(name, raw))
    return false;
  if (raw.getType() != XmlRpc::XmlRpcValue::TypeInt)
    throw core::InvalidInput(name, "must be an integer, got " + raw.toXml());
  value = static_cast<int>(raw);
  return true;
}

std::vector<std::string> NodeHandleParams::names() const {
  std::vector<std::string> all, mine;
  nh_.getParamNames(all);
  const std::string prefix = nh_.getNamespace() + "/";
  for (const std::string& name : all) {
    if (name.rfind(prefix, 0) == 0 && name.find('/', prefix.size()) == std::string::npos)
      mine.push_back(name.substr(prefix.size()));
  }
  return mine;
}

bool NodeHandleParams::get(const std::string& name, bool& value) const {
  return getFromNodeHandle(nh_, name, value, "true or false");
}

}  // namespace lidar_deskew::ros_adapter
