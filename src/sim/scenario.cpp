#include "lidar_deskew/sim/scenario.h"

#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace lidar_deskew::sim {
namespace {

Scenario makeScenario(const LidarModel& lidar, const std::string& speed, const std::string& motion) {
  Scenario scenario;
  scenario.lidar = lidar;
  scenario.speed = speed;
  scenario.motion = motion;
  scenario.name = lidar.name + "/" + speed + "/" + motion;
  const bool high = speed == "high";
  const double v = high ? 6.0 : 1.5;
  const double w = high ? 5.0 : 2.0;
  // The paper mounts the laser off the rotation centre for the high-speed case.
  scenario.mount = high ? Pose2{0.25, 0.05, 0.1} : Pose2{0.0, 0.0, 0.0};
  scenario.start = {-10.0, 0.5, 0.0};
  // About 8 scans for the 8 Hz sensor, 20 for the 40 Hz ones.
  scenario.duration = lidar.rate < 20.0 ? 1.0 : 0.5;
  if (motion == "translation") {
    scenario.pieces = {{scenario.duration, v, 0.0, 0.0}};
  } else if (motion == "rotation") {
    scenario.pieces = {{scenario.duration, 0.0, 0.0, w}};
  } else {
    scenario.pieces = {{scenario.duration, v, 0.0, w}};
  }
  return scenario;
}

}  // namespace

std::vector<Scenario> paperScenarios() {
  std::vector<Scenario> scenarios;
  for (const std::string speed : {"normal", "high"}) {
    for (const LidarModel& lidar :
         {LidarModel::utm30lx360(), LidarModel::ild26tri(), LidarModel::utm30lx270()}) {
      for (const std::string motion : {"translation", "rotation", "arc"}) {
        scenarios.push_back(makeScenario(lidar, speed, motion));
      }
    }
  }
  // Speed and turn rate change inside every scan: every 40 ms the speed ramp flips (1 -> 3 -> 5 -> 3 ->
  // 1 m/s at 50 m/s^2) and the turn rate flips between +4 and -4 rad/s. 40 ms is two periods of 50 Hz
  // odometry, so the changes fall on odometry samples: tf interpolates linearly between samples and
  // could not follow a change between them.
  Scenario varying = makeScenario(LidarModel::ild26tri(), "varying", "varying");
  varying.name = "ILD26TRI/varying/varying";
  varying.mount = {0.25, 0.05, 0.1};
  varying.pieces.clear();
  const double speeds[] = {1.0, 3.0, 5.0, 3.0};
  const double accelerations[] = {50.0, 50.0, -50.0, -50.0};
  for (int k = 0; k < 30; ++k) {
    varying.pieces.push_back({0.04, speeds[k % 4], accelerations[k % 4], (k % 2 == 0) ? 4.0 : -4.0});
  }
  scenarios.push_back(varying);
  return scenarios;
}

Scenario findScenario(const std::string& name) {
  std::string names;
  for (const Scenario& scenario : paperScenarios()) {
    if (scenario.name == name)
      return scenario;
    names += " " + scenario.name;
  }
  throw std::invalid_argument("unknown scenario '" + name + "'; known:" + names);
}

Scenario clockwiseVariant(Scenario scenario) {
  scenario.lidar.clockwise = true;
  scenario.name += "/clockwise";
  return scenario;
}

Pose2 Truth::laserPose(core::TimeNs time) const {
  return trajectory().pose(core::nsToSeconds(time - epoch)).compose(mount);
}

void writeTruth(const Truth& truth, const std::string& path) {
  std::ofstream out(path);
  if (!out)
    throw std::runtime_error("cannot write truth file " + path);
  out << std::setprecision(std::numeric_limits<double>::max_digits10);
  out << "# lidar_deskew simulation truth v1\n";
  out << "scenario " << truth.scenario << "\n";
  out << "epoch_ns " << truth.epoch << "\n";
  out << "range_sigma " << truth.range_sigma << "\n";
  out << "mount " << truth.mount.x << " " << truth.mount.y << " " << truth.mount.yaw << "\n";
  out << "start " << truth.start.x << " " << truth.start.y << " " << truth.start.yaw << "\n";
  for (const MotionPiece& piece : truth.pieces) {
    out << "piece " << piece.duration << " " << piece.speed << " " << piece.acceleration << " "
        << piece.yaw_rate << "\n";
  }
  for (const Segment& segment : truth.world.segments()) {
    out << "wall " << segment.a.x() << " " << segment.a.y() << " " << segment.b.x() << " " << segment.b.y()
        << "\n";
  }
  if (!out)
    throw std::runtime_error("cannot write truth file " + path);
}

Truth readTruth(const std::string& path) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("cannot read truth file " + path);
  Truth truth;
  std::string line;
  int number = 0;
  bool has_epoch = false;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#')
      continue;
    std::istringstream fields(line);
    std::string key;
    fields >> key;
    bool ok = true;
    if (key == "scenario") {
      fields >> std::ws;
      std::getline(fields, truth.scenario);
    } else if (key == "epoch_ns") {
      ok = static_cast<bool>(fields >> truth.epoch);
      has_epoch = ok;
    } else if (key == "range_sigma") {
      ok = static_cast<bool>(fields >> truth.range_sigma);
    } else if (key == "mount") {
      ok = static_cast<bool>(fields >> truth.mount.x >> truth.mount.y >> truth.mount.yaw);
    } else if (key == "start") {
      ok = static_cast<bool>(fields >> truth.start.x >> truth.start.y >> truth.start.yaw);
    } else if (key == "piece") {
      MotionPiece piece;
      ok = static_cast<bool>(fields >> piece.duration >> piece.speed >> piece.acceleration >> piece.yaw_rate);
      truth.pieces.push_back(piece);
    } else if (key == "wall") {
      double ax, ay, bx, by;
      ok = static_cast<bool>(fields >> ax >> ay >> bx >> by);
      truth.world.add({ax, ay}, {bx, by});
    } else {
      ok = false;
    }
    if (!ok)
      throw std::runtime_error(path + ":" + std::to_string(number) + ": malformed line '" + line + "'");
  }
  if (!has_epoch || truth.pieces.empty() || truth.world.segments().empty()) {
    throw std::runtime_error(path + ": not a truth file (needs epoch_ns, piece and wall lines)");
  }
  return truth;
}

}  // namespace lidar_deskew::sim
