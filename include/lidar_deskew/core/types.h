// Basic types shared by the ROS-free core: time, errors.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace lidar_deskew::core {

/// Absolute time [ns] on the clock the scans and poses are stamped with (ROS time: sec * 1e9 + nsec).
/// Integer nanoseconds keep full precision at epoch-sized times; durations are double seconds.
using TimeNs = std::int64_t;

/// Duration [s] -> [ns], rounded to the nearest nanosecond.
inline TimeNs secondsToNs(double seconds) {
  return static_cast<TimeNs>(std::llround(seconds * 1e9));
}

/// Duration [ns] -> [s].
inline double nsToSeconds(TimeNs nanoseconds) {
  return static_cast<double>(nanoseconds) * 1e-9;
}

/// A scan (or point set, or pose sample) that cannot be processed. `field()` names the offending
/// input field (e.g. "time_increment", "intensities") so callers can report it as-is.
class InvalidInput : public std::invalid_argument {
 public:
  InvalidInput(std::string field, const std::string& message)
      : std::invalid_argument(field + ": " + message), field_(std::move(field)) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

/// The motion source cannot tell the base pose at a requested time (outside its coverage).
class MotionUnavailable : public std::runtime_error {
 public:
  MotionUnavailable(TimeNs time, const std::string& message) : std::runtime_error(message), time_(time) {}
  /// The time [ns] that could not be answered.
  TimeNs time() const { return time_; }

 private:
  TimeNs time_;
};

}  // namespace lidar_deskew::core
