#include "lidar_deskew/ros/text_params.h"

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <stdexcept>

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

std::map<std::string, std::string> readParamFile(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error(path + ": cannot read the parameter file");
  std::map<std::string, std::string> values;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto fail = [&](const std::string& why) {
      throw std::runtime_error(path + ":" + std::to_string(number) + ": " + why + ": '" + line + "'");
    };
    const auto trim = [](std::string text) {
      const std::size_t begin = text.find_first_not_of(" \t\r");
      const std::size_t end = text.find_last_not_of(" \t\r");
      return begin == std::string::npos ? std::string() : text.substr(begin, end - begin + 1);
    };
    const std::string text = trim(line);
    if (text.empty() || text[0] == '#' || text.rfind("---", 0) == 0 || text == "...")
      continue;
    if (line[0] == ' ' || line[0] == '\t' || text[0] == '-')
      fail("only flat 'name: value' lines are understood (no nesting, no lists)");
    const std::size_t colon = text.find(':');
    if (colon == std::string::npos || colon == 0)
      fail("expected 'name: value'");
    const std::string name = trim(text.substr(0, colon));
    std::string value = trim(text.substr(colon + 1));
    if (!value.empty() && (value[0] == '"' || value[0] == '\'')) {
      const std::size_t close = value.find(value[0], 1);
      if (close == std::string::npos)
        fail("unterminated quote");
      const std::string rest = trim(value.substr(close + 1));
      if (!rest.empty() && rest[0] != '#')
        fail("text after the quoted value");
      value = value.substr(1, close - 1);
    } else {
      // A comment: '#' at the start or after a blank.
      std::size_t comment = value[0] == '#' ? 0 : std::string::npos;
      for (std::size_t i = 1; i < value.size() && comment == std::string::npos; ++i) {
        if (value[i] == '#' && (value[i - 1] == ' ' || value[i - 1] == '\t'))
          comment = i;
      }
      value = trim(value.substr(0, comment));
      if (value.empty() || value[0] == '{' || value[0] == '[' || value[0] == '|' || value[0] == '>')
        fail("only flat 'name: value' lines are understood (no nesting, no lists)");
      if (value == "True" || value == "TRUE")
        value = "true";
      else if (value == "False" || value == "FALSE")
        value = "false";
    }
    if (!values.emplace(name, value).second)
      fail("'" + name + "' is given twice");
  }
  return values;
}

}  // namespace lidar_deskew::ros_adapter
