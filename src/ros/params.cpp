#include "lidar_deskew/ros/params.h"

#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iterator>

namespace lidar_deskew::ros_adapter {
namespace {

void requireNonNegative(double value, const char* name) {
  if (!std::isfinite(value) || value < 0.0) {
    throw core::InvalidInput(name, "must be a finite number >= 0, got " + std::to_string(value));
  }
}

const char* const kNames[] = {
    "fixed_frame",        "base_frame",        "stamp_at",      "scan_period",
    "max_sweep_duration", "reference",         "knot_interval", "exact",
    "rebin_min_gap",      "rebin_gap_factor",  "tf_timeout",    "on_tf_failure",
    "max_tf_gap",         "max_extrapolation", "queue_size",    "diagnostics_period"};

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

const std::vector<std::string>& DeskewParams::names() {
  static const std::vector<std::string> names(std::begin(kNames), std::end(kNames));
  return names;
}

std::string toString(OnTfFailure value) {
  return value == OnTfFailure::kDrop ? "drop" : "pass_through";
}

DeskewParams DeskewParams::load(const ParamSource& source) {
  DeskewParams params;
  source.get("fixed_frame", params.fixed_frame);
  source.get("base_frame", params.base_frame);
  std::string text;
  if (source.get("stamp_at", text))
    params.timing.stamp_at = core::parseStampAt(text);
  source.get("scan_period", params.timing.scan_period);
  source.get("max_sweep_duration", params.timing.max_sweep_duration);
  if (source.get("reference", text))
    params.deskew.reference = core::parseReference(text);
  source.get("knot_interval", params.deskew.knot_interval);
  source.get("exact", params.exact);
  if (params.exact)
    params.deskew.knot_interval = 0.0;
  source.get("rebin_min_gap", params.rebin.min_gap);
  source.get("rebin_gap_factor", params.rebin.gap_factor);
  source.get("tf_timeout", params.tf_timeout);
  if (source.get("on_tf_failure", text)) {
    if (text == "drop") {
      params.on_tf_failure = OnTfFailure::kDrop;
    } else if (text == "pass_through") {
      params.on_tf_failure = OnTfFailure::kPassThrough;
    } else {
      throw core::InvalidInput("on_tf_failure", "must be 'drop' or 'pass_through', got '" + text + "'");
    }
  }
  source.get("max_tf_gap", params.max_tf_gap);
  source.get("max_extrapolation", params.max_extrapolation);
  source.get("queue_size", params.queue_size);
  source.get("diagnostics_period", params.diagnostics_period);
  params.validate();
  return params;
}

void DeskewParams::validate() const {
  if (fixed_frame.empty())
    throw core::InvalidInput("fixed_frame", "must not be empty");
  if (base_frame.empty())
    throw core::InvalidInput("base_frame", "must not be empty");
  if (fixed_frame == base_frame)
    throw core::InvalidInput("base_frame", "must differ from fixed_frame");
  timing.validate();
  deskew.validate();
  if (deskew.knot_interval == 0.0 && !exact) {
    throw core::InvalidInput("knot_interval", "must be > 0; set exact: true for per-beam lookups");
  }
  rebin.validate();
  requireNonNegative(tf_timeout, "tf_timeout");
  requireNonNegative(max_tf_gap, "max_tf_gap");
  requireNonNegative(max_extrapolation, "max_extrapolation");
  if (max_extrapolation > 1.0)
    throw core::InvalidInput("max_extrapolation", "must be <= 1 s");
  if (queue_size < 1)
    throw core::InvalidInput("queue_size", "must be >= 1");
  if (!std::isfinite(diagnostics_period) || diagnostics_period <= 0.0) {
    throw core::InvalidInput("diagnostics_period", "must be > 0 s");
  }
}

}  // namespace lidar_deskew::ros_adapter
