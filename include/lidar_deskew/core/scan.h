// A planar LIDAR scan without ROS, and its timing model (docs/DESIGN.md §4).
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "lidar_deskew/core/types.h"

namespace lidar_deskew::core {

/// The fields of a sensor_msgs/LaserScan that the correction needs, in the same units and meaning.
/// Beam i has angle `angle_min + i * angle_increment` [rad] (increment < 0: clockwise sensor).
struct PlanarScan {
  TimeNs stamp = 0;                ///< header.stamp [ns]; which beam it refers to: TimingConfig::stamp_at
  float angle_min = 0.0f;          ///< [rad] angle of beam 0
  float angle_max = 0.0f;          ///< [rad] carried through only; the grid is angle_min + i * increment
  float angle_increment = 0.0f;    ///< [rad] signed step between consecutive beams
  float time_increment = 0.0f;     ///< [s] time from beam i to beam i+1; 0 = unknown (fallbacks apply)
  float scan_time = 0.0f;          ///< [s] time between scans (one revolution of the sensor)
  float range_min = 0.0f;          ///< [m] ranges below are not returns
  float range_max = 0.0f;          ///< [m] ranges above are not returns
  std::vector<float> ranges;       ///< [m] one per beam; NaN/inf/out-of-limits = no return
  std::vector<float> intensities;  ///< empty, or one per beam (device units)
};

/// Which beam `header.stamp` refers to. ROS convention: the first beam (start).
enum class StampAt { kStart, kEnd };

/// The beams' order in time: as their index says (the message's time_increment sign), or the reverse
/// (drivers that fill the ranges array against the spin, turtlebot3 #633).
enum class BeamOrder { kAsMessage, kReversed };

/// The time every output point is re-expressed at. Start = the first beam's time.
enum class Reference { kStart, kMiddle, kEnd };

/// Parses "start" | "end". Throws InvalidInput("stamp_at") otherwise.
StampAt parseStampAt(const std::string& text);
/// Parses "start" | "middle" | "end". Throws InvalidInput("reference") otherwise.
Reference parseReference(const std::string& text);
/// Parses "as_message" | "reversed". Throws InvalidInput("beam_order") otherwise.
BeamOrder parseBeamOrder(const std::string& text);
std::string toString(StampAt value);
std::string toString(BeamOrder value);
std::string toString(Reference value);

/// How the per-beam times of a scan are derived.
struct TimingConfig {
  /// `kEnd` for drivers that stamp the scan with its last beam's time.
  StampAt stamp_at = StampAt::kStart;
  /// [s] added to header.stamp before stamp_at applies: the first beam's true time is stamp +
  /// time_offset (stamp_at start). A fixed latency, or "stamped at the end" as -(sweep duration).
  double time_offset = 0.0;
  /// kReversed: beam i is measured where the message puts beam n-1-i in time (same stamp rule: the
  /// stamp is the earliest beam's time with stamp_at start).
  BeamOrder beam_order = BeamOrder::kAsMessage;
  /// [s] one sensor revolution, used when both time_increment and scan_time are 0, or always when
  /// use_scan_period is set. 0 = no fallback: such scans are rejected.
  double scan_period = 0.0;
  /// Beam spacing from scan_period even when the message gives time_increment or scan_time (they are
  /// wrong: another unit, another sensor mode). Needs scan_period > 0.
  bool use_scan_period = false;
  /// [s] sweeps longer than this (first to last beam) are rejected as absurd; at most 60 s.
  double max_sweep_duration = 1.0;

  /// Throws InvalidInput naming the bad field (scan_period < 0 or not finite, max_sweep_duration not
  /// in (0, 60] s, time_offset not finite or beyond +-60 s, use_scan_period without scan_period).
  void validate() const;
};

/// Where a scan's beam spacing in time came from.
enum class TimingSource {
  kTimeIncrement,  ///< the message's own time_increment
  kScanTime,       ///< time_increment was 0: scan_time * |angle_increment| / 2pi
  kScanPeriod,     ///< time_increment and scan_time were 0: configured scan_period, same formula
  kScanPeriodSet,  ///< use_scan_period: scan_period whatever the message says (configured, no fallback)
};

/// The resolved per-beam times of one scan: beam i is measured at first_beam_time + i * beam_period.
struct BeamTiming {
  TimeNs first_beam_time = 0;  ///< [ns] time of beam index 0
  double beam_period = 0.0;    ///< [s] signed time from beam i to beam i+1
  std::size_t beam_count = 0;
  TimingSource source = TimingSource::kTimeIncrement;

  /// [s] time of beam i relative to beam 0.
  double beamOffset(std::size_t i) const { return static_cast<double>(i) * beam_period; }
  /// [ns] absolute time of beam i.
  TimeNs beamTime(std::size_t i) const { return first_beam_time + secondsToNs(beamOffset(i)); }
  /// [ns] time of the earliest and the latest beam (they differ from beam 0 / n-1 when period < 0).
  TimeNs earliestBeamTime() const;
  TimeNs latestBeamTime() const;
  /// [ns] the reference time of this scan.
  TimeNs referenceTime(Reference reference) const;
};

/// Checks a scan's fields; throws InvalidInput naming the first bad one. Accepts an empty scan.
/// Rejected: non-finite angle_min / angle_increment / time_increment / scan_time / range_min,
/// |angle_min| > 4 pi, |angle_increment| > 2 pi, more than 1,000,000 beams, NaN range_max,
/// angle_increment = 0 with more than one beam, negative scan_time or range_min, intensities neither
/// empty nor one per range.
void validateScan(const PlanarScan& scan);

/// Resolves the per-beam times of a validated scan (docs/DESIGN.md §4). With time_increment = 0, a rotating
/// sensor turns 2pi per scan_time, so beams are scan_time * |angle_increment| / 2pi apart (this is
/// scan_time / beams for a 360 deg sensor, and stays right for a 270 deg one); else the same with
/// config.scan_period (always, with use_scan_period). beam_order kReversed negates the spacing; the stamp
/// plus time_offset is then placed by stamp_at on the earliest (start) or latest (end) beam. Throws
/// InvalidInput("time_increment") when no fallback applies, or when the sweep lasts longer than
/// config.max_sweep_duration.
BeamTiming resolveTiming(const PlanarScan& scan, const TimingConfig& config);

/// Which ranges of a scan are returns: finite, above 0 and within [range_min, range_max]. Two
/// comparisons per range (NaN and infinities fail them), for hot loops.
class ReturnTest {
 public:
  explicit ReturnTest(const PlanarScan& scan)
      : lowest_(scan.range_min > 0.0f ? scan.range_min : std::numeric_limits<float>::denorm_min()),
        highest_(std::min(scan.range_max, std::numeric_limits<float>::max())) {}
  bool operator()(float range) const { return range >= lowest_ && range <= highest_; }
  /// The index of the first of `count` ranges without a return; `count` when all have one.
  std::size_t firstWithout(const float* ranges, std::size_t count) const;

 private:
  float lowest_;
  float highest_;
};

}  // namespace lidar_deskew::core
