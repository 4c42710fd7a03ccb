// Where parameter values come from: the ROS parameter server (the node) or text (deskew_bag's options).
#pragma once

#include <string>

namespace lidar_deskew::ros_adapter {

/// Where parameter values come from: the ROS parameter server (the node) or command-line options
/// (deskew_bag). Each getter returns false when the parameter is absent and throws core::InvalidInput
/// naming it when present with a value of the wrong type.
class ParamSource {
 public:
  virtual ~ParamSource() = default;
  virtual bool get(const std::string& name, std::string& value) const = 0;
  virtual bool get(const std::string& name, double& value) const = 0;
  virtual bool get(const std::string& name, int& value) const = 0;
  virtual bool get(const std::string& name, bool& value) const = 0;
};

}  // namespace lidar_deskew::ros_adapter
