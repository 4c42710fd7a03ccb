// Scores a simulated multi-line bag (sim/cloud_bag.h) against its truth: the raw clouds, a
// constant-velocity correction between the sweep's first and last pose (what KISS-ICP-class pipelines
// do), our correction (CloudProcessor with knots), one tf lookup per point, and the noise floor (the
// same clouds corrected with the true trajectory), on the same clouds and the same tf buffer.
#pragma once

#include <string>

#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::eval {

struct CloudEvaluation {
  std::string scenario;
  std::string convention;
  std::size_t clouds = 0;    ///< scored
  std::size_t left_out = 0;  ///< clouds tf does not cover (the recording's edges): not scored
  double range_sigma_mm = 0.0;
  /// Distance of every return to the true surfaces [mm], placed with the sensor's true pose at the
  /// reference time (the first return's time).
  sim::ErrorStats raw;        ///< as measured, no correction
  sim::ErrorStats two_pose;   ///< interpolated (lerp + slerp) between tf's poses at the first and last return
  sim::ErrorStats ours;       ///< CloudProcessor, knots every knot_interval
  sim::ErrorStats per_point;  ///< CloudProcessor with exact: true (one tf lookup per point)
  /// The noise floor: every return re-expressed at the reference time with the TRUE sensor poses (the
  /// truth file's trajectory at the point's own time, relative to the one at the reference time),
  /// plain Eigen, no tf and no MRPT. Only the range noise is left: the best any correction can do.
  sim::ErrorStats truth_corrected;
};

/// Which columns of CloudEvaluation to score: all, or only `ours` (the others left empty, count 0), for
/// comparing settings at a fifth of the cost.
enum class CloudColumns { kAll, kOursOnly };

/// Reads every /tf and /tf_static of the bag into one tf2 buffer, then scores every cloud on
/// params' topic-independent settings (time field found alone unless params say otherwise). Throws
/// std::runtime_error for unreadable bags or truth; a cloud tf does not cover is left out and counted.
CloudEvaluation evaluateCloudBag(const std::string& bag_path, const std::string& truth_path,
                                 const std::string& cloud_topic, const ros_adapter::DeskewParams& params,
                                 CloudColumns columns = CloudColumns::kAll);

}  // namespace lidar_deskew::eval
