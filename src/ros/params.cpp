#include "lidar_deskew/ros/params.h"

#include <cmath>

namespace lidar_deskew::ros_adapter {
namespace {

/// Reads `name` when present; a value of the wrong type is an error naming the parameter.
template <typename T>
void read(const ros::NodeHandle& nh, const std::string& name, T& value) {
  if (!nh.hasParam(name))
    return;
  if (!nh.getParam(name, value)) {
    throw core::InvalidInput(name, "has the wrong type (see README for its type and unit)");
  }
}

void read(const ros::NodeHandle& nh, const std::string& name, double& value) {
  if (!nh.hasParam(name))
    return;
  int integer = 0;
  if (nh.getParam(name, value))
    return;
  if (nh.getParam(name, integer)) {  // YAML "1" is an int; accept it for a double parameter
    value = integer;
    return;
  }
  throw core::InvalidInput(name, "must be a number");
}

void requireNonNegative(double value, const char* name) {
  if (!std::isfinite(value) || value < 0.0) {
    throw core::InvalidInput(name, "must be a finite number >= 0, got " + std::to_string(value));
  }
}

}  // namespace

std::string toString(OnTfFailure value) {
  return value == OnTfFailure::kDrop ? "drop" : "pass_through";
}

DeskewParams DeskewParams::load(const ros::NodeHandle& private_nh) {
  DeskewParams params;
  read(private_nh, "fixed_frame", params.fixed_frame);
  read(private_nh, "base_frame", params.base_frame);
  std::string text = toString(params.timing.stamp_at);
  read(private_nh, "stamp_at", text);
  params.timing.stamp_at = core::parseStampAt(text);
  read(private_nh, "scan_period", params.timing.scan_period);
  read(private_nh, "max_sweep_duration", params.timing.max_sweep_duration);
  text = core::toString(params.deskew.reference);
  read(private_nh, "reference", text);
  params.deskew.reference = core::parseReference(text);
  read(private_nh, "knot_interval", params.deskew.knot_interval);
  read(private_nh, "exact", params.exact);
  if (params.exact)
    params.deskew.knot_interval = 0.0;
  read(private_nh, "rebin_min_gap", params.rebin.min_gap);
  read(private_nh, "rebin_gap_factor", params.rebin.gap_factor);
  read(private_nh, "tf_timeout", params.tf_timeout);
  text = toString(params.on_tf_failure);
  read(private_nh, "on_tf_failure", text);
  if (text == "drop") {
    params.on_tf_failure = OnTfFailure::kDrop;
  } else if (text == "pass_through") {
    params.on_tf_failure = OnTfFailure::kPassThrough;
  } else {
    throw core::InvalidInput("on_tf_failure", "must be 'drop' or 'pass_through', got '" + text + "'");
  }
  read(private_nh, "max_extrapolation", params.max_extrapolation);
  read(private_nh, "queue_size", params.queue_size);
  read(private_nh, "diagnostics_period", params.diagnostics_period);
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
