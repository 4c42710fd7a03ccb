// The parameters that change while a node runs, as dynamic_reconfigure's generated config holds them
// (cfg/DeskewScan.cfg, cfg/DeskewCloud.cfg): read by name, as the parameter table reads any source.
#pragma once

#include <boost/any.hpp>
#include <string>

#include "lidar_deskew/DeskewCloudConfig.h"  // generated from cfg/DeskewCloud.cfg
#include "lidar_deskew/DeskewScanConfig.h"   // generated from cfg/DeskewScan.cfg
#include "lidar_deskew/core/types.h"
#include "lidar_deskew/ros/param_source.h"

namespace lidar_deskew::node {

/// A generated dynamic_reconfigure config (DeskewScanConfig or DeskewCloudConfig) as a parameter
/// source: its parameters by name; the ones it does not offer are absent.
template <class Config>
class ConfigParams final : public ros_adapter::ParamSource {
 public:
  explicit ConfigParams(const Config& config) : config_(config) {}
  bool get(const std::string& name, std::string& value) const override { return read(name, value); }
  bool get(const std::string& name, double& value) const override { return read(name, value); }
  bool get(const std::string& name, int& value) const override { return read(name, value); }
  bool get(const std::string& name, bool& value) const override { return read(name, value); }

 private:
  template <typename T>
  bool read(const std::string& name, T& value) const {
    for (const typename Config::AbstractParamDescriptionConstPtr& description :
         Config::__getParamDescriptions__()) {
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
  const Config& config_;
};

}  // namespace lidar_deskew::node
