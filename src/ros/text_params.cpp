#include "lidar_deskew/ros/text_params.h"

#include <cstdint>
#include <cstdlib>

#include "lidar_deskew/core/types.h"

namespace lidar_deskew::ros_adapter {

bool TextParams::get(const std::string& name, std::string& value) const {
  const auto it = values_.find(name);
  if (it == values_.end())
    return false;
  value = it->second;
  return true;
}

bool TextParams::get(const std::string& name, double& value) const {
  std::string text;
  if (!get(name, text))
    return false;
  char* end = nullptr;
  value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0')
    throw core::InvalidInput(name, "must be a number, got '" + text + "'");
  return true;
}

bool TextParams::get(const std::string& name, int& value) const {
  std::string text;
  if (!get(name, text))
    return false;
  char* end = nullptr;
  const long number = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || number < INT32_MIN || number > INT32_MAX)
    throw core::InvalidInput(name, "must be an integer, got '" + text + "'");
  value = static_cast<int>(number);
  return true;
}

bool TextParams::get(const std::string& name, bool& value) const {
  std::string text;
  if (!get(name, text))
    return false;
  if (text == "true" || text == "1") {
    value = true;
  } else if (text == "false" || text == "0") {
    value = false;
  } else {
    throw core::InvalidInput(name, "must be true or false, got '" + text + "'");
  }
  return true;
}

}  // namespace lidar_deskew::ros_adapter
