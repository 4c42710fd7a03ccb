// Parameters from a ROS node handle's namespace.
#pragma once

#include <ros/node_handle.h>

#include <string>
#include <vector>

#include "lidar_deskew/ros/param_source.h"

namespace lidar_deskew::ros_adapter {

/// Parameters from a node handle's namespace.
class NodeHandleParams final : public ParamSource {
 public:
  explicit NodeHandleParams(const ros::NodeHandle& nh) : nh_(nh) {}
  bool get(const std::string& name, std::string& value) const override;
  bool get(const std::string& name, double& value) const override;
  bool get(const std::string& name, int& value) const override;
  bool get(const std::string& name, bool& value) const override;
  /// The names of the parameters directly in the namespace.
  std::vector<std::string> names() const;

 private:
  const ros::NodeHandle& nh_;
};

}  // namespace lidar_deskew::ros_adapter
