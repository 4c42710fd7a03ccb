#include "lidar_deskew/core/scan.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace lidar_deskew::core {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr double kMaxAngleMin = 4.0 * M_PI;  // [rad]
constexpr std::size_t kMaxBeams = 1'000'000;

void requireFinite(float value, const char* field) {
  if (!std::isfinite(value)) {
    throw InvalidInput(field, "must be finite, got " + std::to_string(value));
  }
}

}  // namespace

StampAt parseStampAt(const std::string& text) {
  if (text == "start")
    return StampAt::kStart;
  if (text == "end")
    return StampAt::kEnd;
  throw InvalidInput("stamp_at", "must be 'start' or 'end', got '" + text + "'");
}

Reference parseReference(const std::string& text) {
  if (text == "start")
    return Reference::kStart;
  if (text == "middle")
    return Reference::kMiddle;
  if (text == "end")
    return Reference::kEnd;
  throw InvalidInput("reference", "must be 'start', 'middle' or 'end', got '" + text + "'");
}

BeamOrder parseBeamOrder(const std::string& text) {
  if (text == "as_message")
    return BeamOrder::kAsMessage;
  if (text == "reversed")
    return BeamOrder::kReversed;
  throw InvalidInput("beam_order", "must be 'as_message' or 'reversed', got '" + text + "'");
}

std::string toString(BeamOrder value) {
  return value == BeamOrder::kAsMessage ? "as_message" : "reversed";
}

std::string toString(StampAt value) {
  return value == StampAt::kStart ? "start" : "end";
}

std::string toString(Reference value) {
  switch (value) {
    case Reference::kStart:
      return "start";
    case Reference::kMiddle:
      return "middle";
    case Reference::kEnd:
      return "end";
  }
  return "?";
}

void TimingConfig::validate() const {
  if (max_sweep_duration > 60.0) {
    throw InvalidInput("max_sweep_duration", "must be <= 60 s, got " + std::to_string(max_sweep_duration));
  }
  if (!std::isfinite(scan_period) || scan_period < 0.0) {
    throw InvalidInput("scan_period", "must be >= 0 s (0 = no fallback), got " + std::to_string(scan_period));
  }
  if (!std::isfinite(max_sweep_duration) || max_sweep_duration <= 0.0) {
    throw InvalidInput("max_sweep_duration", "must be > 0 s, got " + std::to_string(max_sweep_duration));
  }
  if (!std::isfinite(time_offset) || std::abs(time_offset) > 60.0)
    throw InvalidInput("time_offset", "must be within +-60 s, got " + std::to_string(time_offset));
  if (use_scan_period && scan_period <= 0.0)
    throw InvalidInput("use_scan_period", "needs scan_period > 0");
}

TimeNs BeamTiming::earliestBeamTime() const {
  return beam_period >= 0.0 || beam_count == 0 ? first_beam_time : beamTime(beam_count - 1);
}

TimeNs BeamTiming::latestBeamTime() const {
  return beam_period < 0.0 || beam_count == 0 ? first_beam_time : beamTime(beam_count - 1);
}

TimeNs BeamTiming::referenceTime(Reference reference) const {
  const TimeNs earliest = earliestBeamTime();
  const TimeNs latest = latestBeamTime();
  switch (reference) {
    case Reference::kStart:
      return earliest;
    case Reference::kEnd:
      return latest;
    case Reference::kMiddle:
      return earliest + (latest - earliest) / 2;
  }
  return earliest;
}

void validateScan(const PlanarScan& scan) {
  requireFinite(scan.angle_min, "angle_min");
  requireFinite(scan.angle_increment, "angle_increment");
  if (std::abs(scan.angle_min) > kMaxAngleMin) {
    throw InvalidInput("angle_min", "must be within +-4 pi rad, got " + std::to_string(scan.angle_min));
  }
  if (std::abs(scan.angle_increment) > kTwoPi) {
    throw InvalidInput("angle_increment",
                       "must be within +-2 pi rad, got " + std::to_string(scan.angle_increment));
  }
  if (scan.ranges.size() > kMaxBeams) {
    throw InvalidInput(
        "ranges", "has " + std::to_string(scan.ranges.size()) + " beams, above " + std::to_string(kMaxBeams));
  }
  requireFinite(scan.time_increment, "time_increment");
  requireFinite(scan.scan_time, "scan_time");
  requireFinite(scan.range_min, "range_min");
  if (std::isnan(scan.range_max))
    throw InvalidInput("range_max", "must not be NaN");
  if (scan.ranges.size() > 1 && scan.angle_increment == 0.0f) {
    throw InvalidInput("angle_increment",
                       "is 0 for a scan of " + std::to_string(scan.ranges.size()) + " beams");
  }
  if (scan.scan_time < 0.0f)
    throw InvalidInput("scan_time", "must be >= 0, got " + std::to_string(scan.scan_time));
  if (scan.range_min < 0.0f)
    throw InvalidInput("range_min", "must be >= 0, got " + std::to_string(scan.range_min));
  if (!scan.intensities.empty() && scan.intensities.size() != scan.ranges.size()) {
    throw InvalidInput("intensities", "has " + std::to_string(scan.intensities.size()) + " values for " +
                                          std::to_string(scan.ranges.size()) + " ranges");
  }
}

BeamTiming resolveTiming(const PlanarScan& scan, const TimingConfig& config) {
  BeamTiming timing;
  timing.beam_count = scan.ranges.size();
  const double revolution_share = std::abs(static_cast<double>(scan.angle_increment)) / kTwoPi;
  if (config.use_scan_period) {
    timing.beam_period = config.scan_period * revolution_share * (scan.time_increment < 0.0f ? -1.0 : 1.0);
    timing.source = TimingSource::kScanPeriodSet;
  } else if (scan.time_increment != 0.0f) {
    timing.beam_period = scan.time_increment;
    timing.source = TimingSource::kTimeIncrement;
  } else if (scan.scan_time > 0.0f) {
    timing.beam_period = static_cast<double>(scan.scan_time) * revolution_share;
    timing.source = TimingSource::kScanTime;
  } else if (config.scan_period > 0.0) {
    timing.beam_period = config.scan_period * revolution_share;
    timing.source = TimingSource::kScanPeriod;
  } else if (timing.beam_count > 1) {
    throw InvalidInput(
        "time_increment",
        "is 0 and so is scan_time; set the scan_period parameter to the sensor's revolution time");
  }
  if (config.beam_order == BeamOrder::kReversed)
    timing.beam_period = -timing.beam_period;
  const double sweep =
      std::abs(timing.beam_period) * static_cast<double>(timing.beam_count > 0 ? timing.beam_count - 1 : 0);
  if (sweep > config.max_sweep_duration) {
    std::ostringstream message;
    message << "gives a sweep of " << sweep << " s over " << timing.beam_count
            << " beams, above max_sweep_duration " << config.max_sweep_duration << " s";
    throw InvalidInput("time_increment", message.str());
  }
  const TimeNs sweep_ns = secondsToNs(sweep);
  // With a negative period the latest beam is beam 0, the earliest beam n-1.
  const TimeNs stamp = scan.stamp + secondsToNs(config.time_offset);
  const bool stamp_is_beam0 = (config.stamp_at == StampAt::kStart) == (timing.beam_period >= 0.0);
  timing.first_beam_time = stamp_is_beam0                     ? stamp
                           : config.stamp_at == StampAt::kEnd ? stamp - sweep_ns
                                                              : stamp + sweep_ns;
  return timing;
}

std::size_t ReturnTest::firstWithout(const float* ranges, std::size_t count) const {
  std::size_t i = 0;
#if defined(__SSE2__)
  // Most beams have a return: four at a time are passed over while all four do (SSE2 is part of x86-64;
  // the comparisons are the scalar test's, NaN failing both).
  const __m128 lowest = _mm_set1_ps(lowest_), highest = _mm_set1_ps(highest_);
  for (; i + 4 <= count; i += 4) {
    const __m128 range = _mm_loadu_ps(ranges + i);
    if (_mm_movemask_ps(_mm_and_ps(_mm_cmpge_ps(range, lowest), _mm_cmple_ps(range, highest))) != 0xF)
      break;
  }
#endif
  while (i < count && (*this)(ranges[i]))
    ++i;
  return i;
}

}  // namespace lidar_deskew::core
