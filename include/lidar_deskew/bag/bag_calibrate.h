// deskew_calibrate: a planar LIDAR's timing (time_offset, beam_order, period) estimated from a
// recording in which the robot turns (docs/CALIBRATION.md), written as a parameter file the node
// (`params:=FILE`) and deskew_bag (`--params FILE`) read.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "lidar_deskew/core/scan_match.h"
#include "lidar_deskew/core/timing_fit.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::bag {

struct CalibrateOptions {
  std::string input;       ///< the bag
  std::string scan_topic;  ///< empty: the bag's only LaserScan topic
  /// fixed_frame, base_frame (the timing parameters are what is estimated; the rest is unused)
  ros_adapter::DeskewParams params;
  core::TimingFitConfig fit;
  /// Scans the fit gets at most: a longer recording gives whole segments of `segment` [s], those that
  /// turn most (chooseScans): memory and time stay bounded whatever the recording's length.
  std::size_t max_scans = 1200;
  double segment = 10.0;
  /// Told what is being done as each stage starts (a minute or more on a long recording); may be empty.
  std::function<void(const std::string&)> progress;
};

/// Which of a recording's scans (stamps [ns] in order, the base's turn rate [rad/s] at each) to keep:
/// all when at most `max_scans`; else whole segments of `segment` [s], best first by their share of
/// scans turning at `turning_rate` or faster plus their share of changes of turn rate (starting and
/// stopping), until `max_scans`.
std::vector<char> chooseScans(const std::vector<core::TimeNs>& stamps, const std::vector<double>& turn_rates,
                              std::size_t max_scans, double segment, double turning_rate);

struct Calibration {
  std::string scan_topic;
  std::string frame;  ///< the scans' frame
  std::size_t beams = 0;
  double stamp_period = 0.0;        ///< [s] from the stamps
  double stamp_period_sigma = 0.0;  ///< [s]
  double sweep = 0.0;               ///< [s] first to last beam under the estimated period
  std::size_t unusable_stamps = 0;  ///< scans left out: a stamp tf cannot take (0, another clock)
  std::size_t not_chosen = 0;       ///< scans left out to keep within max_scans (chooseScans)
  /// Frames other than `frame` that the topic's scans have (a frame_id that changes midway), with
  /// their scans' counts: those scans are left out
  std::vector<std::pair<std::string, std::size_t>> other_frames;
  std::size_t other_frame_scans = 0;
  core::TimingEstimate estimate;
  /// What the bag's tf did (loaded by the live node's rules): time jumps (each cleared the tf read
  /// before it), transforms left out as off the scans' time line (stale, ahead), refused.
  std::size_t tf_time_jumps = 0, tf_stale = 0, tf_ahead = 0, tf_refused = 0;
  /// The shape check (core/scan_match.h), which odometry between scans cannot spoil: scans a short
  /// time apart whose turn differs, aligned by a free rigid scan match, corrected / raw under the
  /// message's timing and under the estimate (when told), and tf's rotation between consecutive scans
  /// against the scans' under the estimate (else the message's). An estimate that makes shapes worse
  /// than raw is not told (TimingCause::kWorseThanRaw), whatever the overlap score says.
  bool shapes_checked = false;       ///< false: the check failed (`shape_error`)
  std::string shape_error;
  core::ShapeRatio shapes_message;   ///< under the message's timing
  core::ShapeRatio shapes_estimate;  ///< under the estimate (when told)
  core::RotationAgreement rotation;
  std::vector<std::string> shape_warnings;  ///< core::shapeWarnings under the timing written (or kept)
};

/// Reads the scans of the topic and the bag's tf (the live node's rules), and estimates. Throws
/// std::runtime_error for an unreadable bag, a missing or ambiguous topic, no tf between the frames.
Calibration calibrateBag(const CalibrateOptions& options);

/// The estimate as a flat parameter file: the timing parameters, each with a comment, and a header
/// saying what was measured. Throws std::runtime_error when it cannot be written.
void writeTimingParams(const Calibration& calibration, const std::string& bag, const std::string& path);

/// The chosen beam order's and period's score against the offset, as CSV (search,offset_s,score_m).
void writeCurve(const Calibration& calibration, const std::string& path);

/// The estimate for the user, several lines.
std::string describe(const Calibration& calibration);

}  // namespace lidar_deskew::bag
