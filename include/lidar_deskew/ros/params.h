// The node's parameters: read once from the private namespace into one validated struct.
#pragma once

#include <ros/node_handle.h>

#include <map>
#include <string>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/core/scan.h"

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

/// Parameters from a node handle's namespace.
class NodeHandleParams final : public ParamSource {
 public:
  explicit NodeHandleParams(const ros::NodeHandle& nh) : nh_(nh) {}
  bool get(const std::string& name, std::string& value) const override;
  bool get(const std::string& name, double& value) const override;
  bool get(const std::string& name, int& value) const override;
  bool get(const std::string& name, bool& value) const override;

 private:
  const ros::NodeHandle& nh_;
};

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

/// What to do with a scan whose sweep tf does not cover within tf_timeout.
enum class OnTfFailure { kDrop, kPassThrough };

struct DeskewParams {
  std::string fixed_frame = "odom";      ///< frame the base moves in
  std::string base_frame = "base_link";  ///< the robot's base; the mount is base -> scan frame
  core::TimingConfig timing;             ///< stamp_at, scan_period [s], max_sweep_duration [s]
  core::DeskewConfig deskew;             ///< reference, knot_interval [s] (0 when exact)
  core::RebinConfig rebin;               ///< rebin_min_gap [m], rebin_gap_factor
  bool exact = false;                    ///< look tf up for every beam (verification, benchmarks)
  double tf_timeout = 0.2;               ///< [s] longest wait for tf to cover a sweep's last beam
  OnTfFailure on_tf_failure = OnTfFailure::kDrop;
  double max_tf_gap = 0.5;          ///< [s] refuse sweeps tf interpolates across a longer gap; 0 = never
  double max_extrapolation = 0.0;   ///< [s] extrapolate tf this far with the newest velocity; 0 = never
  int queue_size = 10;              ///< scans waiting for tf at most (older ones are dropped)
  double diagnostics_period = 1.0;  ///< [s]

  /// Reads every parameter (defaults above for the absent ones) and validates. Throws
  /// core::InvalidInput naming the parameter for a bad value or type.
  static DeskewParams load(const ParamSource& source);
  static DeskewParams load(const ros::NodeHandle& private_nh) { return load(NodeHandleParams(private_nh)); }
  /// The names load() reads.
  static const std::vector<std::string>& names();
  /// Throws core::InvalidInput naming the first bad parameter.
  void validate() const;
};

std::string toString(OnTfFailure value);

}  // namespace lidar_deskew::ros_adapter
