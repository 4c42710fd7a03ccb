// Parameters given as text (deskew_bag's command-line options).
#pragma once

#include <map>
#include <string>

#include "lidar_deskew/ros/param_source.h"

namespace lidar_deskew::ros_adapter {

/// Parameters given as text, name -> value (numbers as decimal text, booleans as true/false/1/0).
class TextParams final : public ParamSource {
 public:
  explicit TextParams(std::map<std::string, std::string> values) : values_(std::move(values)) {}
  bool get(const std::string& name, std::string& value) const override;
  bool get(const std::string& name, double& value) const override;
  bool get(const std::string& name, int& value) const override;
  bool get(const std::string& name, bool& value) const override;

 private:
  std::map<std::string, std::string> values_;
};

/// Reads a parameter file as `rosparam load` would for our flat parameters: one `name: value` per
/// line, `#` comments, blank lines, values plain or in single or double quotes. Throws
/// std::runtime_error naming the file and line for anything else (nesting, lists, a line without a
/// name, a name given twice, an unreadable file).
std::map<std::string, std::string> readParamFile(const std::string& path);

}  // namespace lidar_deskew::ros_adapter
