// The parameters that change while the node runs, as dynamic_reconfigure's generated config holds them
// (cfg/Deskew.cfg): read by name, as the parameter table reads any source.
#pragma once

#include <boost/any.hpp>
#include <string>

#include "lidar_deskew/DeskewConfig.h"  // generated from cfg/Deskew.cfg
#include "lidar_deskew/core/types.h"
#include "lidar_deskew/ros/param_source.h"

namespace lidar_deskew::node {

/// A generated dynamic_reconfigure config as a parameter source: its parameters by name.
class ConfigParams final : public ros_adapter::ParamSource {
 public:
  explicit ConfigParams(const DeskewConfig& config) : config_(config) {}
  bool get(const std::string& name, std::string& value) const override { return read(name, value); }
  bool get(const std::string& name, double& value) const override { return read(name, value); }
  bool get(const std::string& name, int& value) const override { return read(name, value); }
  bool get(const std::string& name, bool& value) const override { return read(name, value); }

 private:
  template <typename T>
  bool read(const std::string& name, T& value) const {
    for (const DeskewConfig::AbstractParamDescriptionConstPtr& description :
         DeskewConfig::__getParamDescriptions__()) {
      if (description->name != name)
        continue;
      boost::any any;
      description->getValue(config_, any);
      const T* typed = boost::any_cast<T>(&any);
      if (typed == nullptr)
        throw core::InvalidInput(name, "has type " + description->type);
      value = *typed;
      return true;
    }
    return false;
  }
  const DeskewConfig& config_;
};

}  // namespace lidar_deskew::node
