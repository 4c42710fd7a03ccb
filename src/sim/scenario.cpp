#include "lidar_deskew/sim/scenario.h"

#include <stdexcept>

#include "truth_text.h"

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
  return truth_text::findByName(paperScenarios(), name, "scenario");
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
  std::ofstream out = truth_text::create(path, "lidar_deskew simulation truth v1");
  out << "scenario " << truth.scenario << "\n";
  out << "epoch_ns " << truth.epoch << "\n";
  out << "range_sigma " << truth.range_sigma << "\n";
  out << "mount " << truth.mount.x << " " << truth.mount.y << " " << truth.mount.yaw << "\n";
  truth_text::writeMotion(out, truth.start, truth.pieces);
  for (const Segment& segment : truth.world.segments()) {
    out << "wall " << segment.a.x() << " " << segment.a.y() << " " << segment.b.x() << " " << segment.b.y()
        << "\n";
  }
  truth_text::finish(out, path);
}

Truth readTruth(const std::string& path) {
  Truth truth;
  bool has_epoch = false;
  truth_text::readLines(path, [&](const std::string& key, std::istringstream& fields) {
    if (key == "scenario") {
      truth.scenario = truth_text::rest(fields);
      return true;
    }
    if (key == "epoch_ns")
      return has_epoch = static_cast<bool>(fields >> truth.epoch);
    if (key == "range_sigma")
      return static_cast<bool>(fields >> truth.range_sigma);
    if (key == "mount")
      return static_cast<bool>(fields >> truth.mount.x >> truth.mount.y >> truth.mount.yaw);
    if (key == "wall") {
      double ax, ay, bx, by;
      const bool ok = static_cast<bool>(fields >> ax >> ay >> bx >> by);
      truth.world.add({ax, ay}, {bx, by});
      return ok;
    }
    return truth_text::readMotion(key, fields, &truth.start, &truth.pieces);
  });
  if (!has_epoch || truth.pieces.empty() || truth.world.segments().empty()) {
    throw std::runtime_error(path + ": not a truth file (needs epoch_ns, piece and wall lines)");
  }
  return truth;
}

}  // namespace lidar_deskew::sim
