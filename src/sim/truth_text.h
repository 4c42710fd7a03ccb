// What the planar and the cloud truth files (scenario.h, cloud_scenario.h) and the scenario lists
// share: line-based text at full double precision, the planar motion's lines, lookup by name.
// Private to src/sim.
#pragma once

#include <fstream>
#include <functional>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidar_deskew/sim/scenario.h"
#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::sim::truth_text {

/// Opens `path` for writing at full double precision with the comment line `# <title>`; throws
/// std::runtime_error if it cannot.
inline std::ofstream create(const std::string& path, const std::string& title) {
  std::ofstream out(path);
  if (!out)
    throw std::runtime_error("cannot write truth file " + path);
  out << std::setprecision(std::numeric_limits<double>::max_digits10) << "# " << title << "\n";
  return out;
}

/// Throws std::runtime_error if writing `path` failed.
inline void finish(const std::ofstream& out, const std::string& path) {
  if (!out)
    throw std::runtime_error("cannot write truth file " + path);
}

/// "start x y yaw", then one "piece duration speed acceleration yaw_rate" per piece.
inline void writeMotion(std::ostream& out, const Pose2& start, const std::vector<MotionPiece>& pieces) {
  out << "start " << start.x << " " << start.y << " " << start.yaw << "\n";
  for (const MotionPiece& piece : pieces) {
    out << "piece " << piece.duration << " " << piece.speed << " " << piece.acceleration << " "
        << piece.yaw_rate << "\n";
  }
}

/// Reads a "start" or "piece" line's fields into `start` / `pieces`: whether they parsed. False
/// also for another key.
inline bool readMotion(const std::string& key, std::istream& fields, Pose2* start,
                       std::vector<MotionPiece>* pieces) {
  if (key == "start")
    return static_cast<bool>(fields >> start->x >> start->y >> start->yaw);
  if (key != "piece")
    return false;
  MotionPiece piece;
  const bool ok =
      static_cast<bool>(fields >> piece.duration >> piece.speed >> piece.acceleration >> piece.yaw_rate);
  pieces->push_back(piece);
  return ok;
}

/// The odometry's lines: "odom_noise R", "odom_noise_seed N"; "odom_yaw_scale F" only when not 1;
/// "odom_jitter S", "odom_rate LO HI", "odom_ticks M B", "odom_late S", "odom_burst N" only when set.
inline void writeOdometry(std::ostream& out, double noise, unsigned seed, double yaw_scale,
                          const OdometryTiming& timing) {
  out << "odom_noise " << noise << "\n";
  out << "odom_noise_seed " << seed << "\n";
  if (yaw_scale != 1.0)
    out << "odom_yaw_scale " << yaw_scale << "\n";
  if (timing.jitter != 0.0)
    out << "odom_jitter " << timing.jitter << "\n";
  if (timing.rate_min != 0.0)
    out << "odom_rate " << timing.rate_min << " " << timing.rate_max << "\n";
  if (timing.tick != 0.0)
    out << "odom_ticks " << timing.tick << " " << timing.wheel_base << "\n";
  if (timing.late != 0.0)
    out << "odom_late " << timing.late << "\n";
  if (timing.burst != 1)
    out << "odom_burst " << timing.burst << "\n";
}

/// Reads one of writeOdometry's lines into the fields: whether it parsed. False also for another key.
inline bool readOdometry(const std::string& key, std::istream& fields, double* noise, unsigned* seed,
                         double* yaw_scale, OdometryTiming* timing) {
  if (key == "odom_noise")
    return static_cast<bool>(fields >> *noise);
  if (key == "odom_noise_seed")
    return static_cast<bool>(fields >> *seed);
  if (key == "odom_yaw_scale")
    return static_cast<bool>(fields >> *yaw_scale);
  if (key == "odom_jitter")
    return static_cast<bool>(fields >> timing->jitter);
  if (key == "odom_rate")
    return static_cast<bool>(fields >> timing->rate_min >> timing->rate_max);
  if (key == "odom_ticks")
    return static_cast<bool>(fields >> timing->tick >> timing->wheel_base);
  if (key == "odom_late")
    return static_cast<bool>(fields >> timing->late);
  if (key == "odom_burst")
    return static_cast<bool>(fields >> timing->burst);
  return false;
}

/// Calls `line(key, fields)` for every line of `path` but blank ones and comments; `line` tells
/// whether the line was good. Throws std::runtime_error naming the file (and line) otherwise.
inline void readLines(const std::string& path,
                      const std::function<bool(const std::string& key, std::istringstream& fields)>& line) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("cannot read truth file " + path);
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (text.empty() || text[0] == '#')
      continue;
    std::istringstream fields(text);
    std::string key;
    fields >> key;
    if (!line(key, fields))
      throw std::runtime_error(path + ":" + std::to_string(number) + ": malformed line '" + text + "'");
  }
}

/// The rest of the line after the key, leading blanks skipped.
inline std::string rest(std::istream& fields) {
  std::string value;
  std::getline(fields >> std::ws, value);
  return value;
}

/// The item of `items` whose `name` is `name`; throws std::invalid_argument listing the names.
template <typename T>
T findByName(const std::vector<T>& items, const std::string& name, const std::string& what) {
  std::string names;
  for (const T& item : items) {
    if (item.name == name)
      return item;
    names += " " + item.name;
  }
  throw std::invalid_argument("unknown " + what + " '" + name + "'; known:" + names);
}

}  // namespace lidar_deskew::sim::truth_text
