// Scores a simulated bag against its truth: raw scans, our correction (cloud and re-binned scan) and
// laser_geometry's fixed-frame transformLaserScanToPointCloud, on the same scans and the same tf buffer.
#pragma once

#include <string>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::eval {

/// Distance statistics; in an Evaluation, in mm.
using sim::ErrorStats;

struct EvaluateOptions {
  std::string scan_topic = "/scan";
  std::string fixed_frame = "odom";
  std::string base_frame = "base_link";
  core::DeskewConfig deskew;  ///< reference start (what laser_geometry gives), knots every 5 ms
  core::TimingConfig timing;  ///< the scans' timing (time_offset, beam_order, ...): ROS's by default
  core::RebinConfig rebin;
  /// When not empty: a CSV of one scan (index figure_scan) for the figures: walls, trajectory, raw,
  /// corrected and laser_geometry points, all in the laser frame at that scan's reference time.
  std::string figure_csv;
  std::size_t figure_scan = 0;
};

struct Evaluation {
  std::string scenario;
  std::size_t scans = 0;     ///< scored
  std::size_t left_out = 0;  ///< scans tf does not cover (the recording's edges): not scored
  double range_sigma_mm = 0.0;
  /// Distance of every point to the true walls [mm].
  ErrorStats raw;    ///< raw beams drawn in the laser frame at the scan stamp
  ErrorStats cloud;  ///< our corrected points
  ErrorStats scan;   ///< our re-binned LaserScan's endpoints
  /// Of the re-binned LaserScan's bins with a return (scan.count), those whose endpoint lies farther than
  /// 10 mm from the true walls.
  std::size_t scan_over_1cm = 0;
  /// The truth-corrected scan: every beam's true hit, in the true laser frame at the reference time,
  /// re-binned alike. Its bins with a return, and how many of those our scan leaves empty.
  std::size_t truth_scan_filled = 0;
  std::size_t scan_emptied = 0;
  ErrorStats laser_geometry;  ///< laser_geometry, target = laser frame at the stamp, fixed = odom
  /// Distance of our corrected points to their own beam's true hit point [mm] (noise shows in full).
  ErrorStats cloud_to_hit;
  /// What range noise alone gives as distance to the walls [mm]: sigma * rms(cos incidence).
  double noise_only_rms = 0.0;
};

/// Reads every /tf and /tf_static of the bag into one tf2 buffer, then scores every scan tf covers (the
/// others are left out and counted). Throws std::runtime_error for unreadable bags or truth, and when
/// tf covers no scan.
Evaluation evaluateBag(const std::string& bag_path, const std::string& truth_path,
                       const EvaluateOptions& options);

}  // namespace lidar_deskew::eval
