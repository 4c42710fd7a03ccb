// The parameters of the node and deskew_bag: one table (ParamSpec) and one validated struct.
#pragma once

#include <string>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/ros/cloud_azimuth.h"
#include "lidar_deskew/ros/cloud_timing.h"
#include "lidar_deskew/ros/node_handle_params.h"
#include "lidar_deskew/ros/param_source.h"
#include "lidar_deskew/ros/text_params.h"

namespace lidar_deskew::ros_adapter {

/// What to do with a scan whose sweep tf does not cover within tf_timeout.
enum class OnTfFailure { kDrop, kPassThrough };

/// The input a parameter applies to: both, LaserScans only (the scan node, deskew_bag's scans) or
/// PointCloud2s only.
enum class Input { kBoth, kScans, kClouds };

/// One parameter as users see it: the one place its name, type, default, unit and bounds are written.
/// config/deskew.yaml and the docs' table are checked against these by test_deskew_params.
struct ParamSpec {
  const char* name;
  const char* type;           ///< "string", "double", "int" or "bool"
  const char* default_value;  ///< as written in YAML
  const char* unit;           ///< "" when none
  double min;                 ///< numbers: the smallest value allowed (exclusive when min_exclusive)
  double max;                 ///< numbers: the largest value allowed
  bool min_exclusive;
  const char* choices;  ///< strings with fixed values, e.g. "start|middle|end"; "" for free text
  bool live_only;       ///< means nothing offline: deskew_bag refuses it
  bool reconfigurable;  ///< may change while the node runs (dynamic_reconfigure, cfg/Deskew*.cfg)
  const char* meaning;
  Input input = Input::kBoth;  ///< the input it applies to

  /// Whether the node of `node` (kScans or kClouds) reads it.
  bool readBy(Input node) const { return input == Input::kBoth || input == node; }

  /// The allowed values as the docs' table shows them: "[0, 60]", "(0, 3600]", "start, end", "".
  std::string bounds() const;
};

struct DeskewParams {
  std::string fixed_frame = "odom";      ///< frame the base moves in (normalised: no leading '/')
  std::string base_frame = "base_link";  ///< the robot's base; the mount is base -> scan frame
  core::TimingConfig timing;             ///< stamp_at, scan_period [s], max_sweep_duration [s]
  core::DeskewConfig deskew;             ///< reference, knot_interval [s] (0 when exact)
  core::RebinConfig rebin;               ///< rebin_min_gap [m], rebin_gap_factor
  CloudTimeConfig cloud_time;            ///< clouds: time_field, time_unit, time_base
  /// Clouds without a time field: azimuth_timing, azimuth_direction, azimuth_period [s], azimuth_stamp_at.
  AzimuthTiming azimuth;
  /// Clouds: the planar LaserScan of the corrected points (pointcloud_to_laserscan's job, after the
  /// correction): cloud_scan, scan_height_min/max [m], scan_angle_min/max/increment [rad], scan_range_max
  /// [m].
  struct CloudScan {
    bool enabled = false;
    double height_min = -0.1;
    double height_max = 0.1;
    double angle_min = -3.14159;
    double angle_max = 3.14159;
    double angle_increment = 0.00436332;
    double range_max = 100.0;
  } cloud_scan;
  bool exact = false;       ///< look tf up for every beam (verification, benchmarks)
  double tf_timeout = 0.2;  ///< [s] longest wait for tf to cover a sweep's last beam
  OnTfFailure on_tf_failure = OnTfFailure::kDrop;
  double max_tf_gap = 0.5;          ///< [s] refuse sweeps tf interpolates across a longer gap; 0 = never
  double max_extrapolation = 0.0;   ///< [s] extrapolate tf this far with the newest velocity; 0 = never
  int queue_size = 10;              ///< scans waiting for tf at most (older ones are dropped)
  int input_queue_size = 10;        ///< roscpp's queue of the input subscription (live only)
  double diagnostics_period = 1.0;  ///< [s]

  /// Reads every parameter (defaults above for the absent ones) and validates. Throws
  /// core::InvalidInput naming the parameter for a bad value or type.
  static DeskewParams load(const ParamSource& source);
  /// The same, parameters absent from `source` keeping their value in `base`.
  static DeskewParams load(const ParamSource& source, const DeskewParams& base);
  static DeskewParams load(const ros::NodeHandle& private_nh) { return load(NodeHandleParams(private_nh)); }
  /// Every parameter, in the order of config/deskew.yaml.
  static const std::vector<ParamSpec>& specs();
  /// The names load() reads, and those of them that only the live node uses.
  static const std::vector<std::string>& names();
  static const std::vector<std::string>& liveOnlyNames();
  /// The names of the parameters that may change while the node runs (dynamic_reconfigure).
  static const std::vector<std::string>& reconfigurableNames();
  /// Of them, those the node of `node` (kScans or kClouds) reads: what its dynamic_reconfigure offers.
  static std::vector<std::string> reconfigurableNames(Input node);
  /// Throws core::InvalidInput naming the first parameter outside its bounds (specs()).
  void validate() const;
  /// Of `given` names, those that are no parameter, each with the closest parameter name when one is
  /// near (a misspelling): "tf_timout (did you mean tf_timeout?)".
  static std::vector<std::string> unknownNames(const std::vector<std::string>& given);
};

std::string toString(OnTfFailure value);

/// Of `candidates`, the one closest to `name` by edit distance when at most two edits away (a
/// misspelling: "odm" -> "odom"); empty when none is.
std::string closestName(const std::string& name, const std::vector<std::string>& candidates);

}  // namespace lidar_deskew::ros_adapter
