#include "lidar_deskew/sim/cloud_scenario.h"

#include <cmath>
#include <stdexcept>

#include "truth_text.h"

namespace lidar_deskew::sim {
namespace {

constexpr double kDegree = M_PI / 180.0;
/// [s] The smooth drives: one period of the turn rate (13 sweeps at 10 Hz), as the planar ones.
constexpr double kSmoothDuration = 1.3;

std::shared_ptr<const Trajectory3> makeTrajectory(const Pose2& start, const std::vector<MotionPiece>& pieces,
                                                  const std::optional<RoughGround>& rough) {
  auto planar = std::make_shared<const PiecewiseTrajectory>(start, pieces);
  if (rough)
    return std::make_shared<const RoughGroundTrajectory3>(planar, *rough);
  return std::make_shared<const PlanarTrajectory3>(planar);
}

CloudScenario makeScenario(const SpinningLidarModel& lidar, const std::string& speed,
                           const std::string& motion) {
  CloudScenario scenario;
  scenario.name = lidar.name + "/" + speed + "/" + motion;
  scenario.lidar = lidar;
  scenario.speed = speed;
  scenario.motion = motion;
  const bool fast = speed == "high" || speed == "varying";
  scenario.mount = fast ? Pose3::fromXyzRpy(0.25, 0.05, 0.6, 1.0 * kDegree, 2.0 * kDegree, 0.1)
                        : Pose3::fromXyzRpy(0.1, 0.0, 0.5, 1.0 * kDegree, 2.0 * kDegree, 0.0);
  scenario.start = {-10.0, 0.5, 0.0};
  scenario.duration = 1.0;
  const double v = speed == "high" ? 6.0 : 1.5;
  const double w = speed == "high" ? 5.0 : 2.0;
  if (motion == "still") {
    scenario.pieces = {{scenario.duration, 0.0, 0.0, 0.0}};
  } else if (motion == "turn") {
    scenario.pieces = {{scenario.duration, 0.0, 0.0, w}};
  } else if (motion == "arc") {
    scenario.pieces = {{scenario.duration, v, 0.0, w}};
  } else if (motion == "smooth") {
    // As the planar smooth drives (smoothScenarios): speed and turn rate follow cosines, so the twist
    // changes between any two tf samples. Pieces to well past the last sweep and tf's margin.
    scenario.start = {-10.0, -1.5, 0.0};
    scenario.duration = kSmoothDuration;
    scenario.pieces = smoothUnicyclePieces(v, w, kSmoothDuration + 1.0);
  } else {
    // As ILD26TRI/varying/varying: every 40 ms (two periods of 50 Hz tf) the speed ramp flips
    // (1 -> 3 -> 5 -> 3 -> 1 m/s at 50 m/s^2) and the turn rate flips between +4 and -4 rad/s.
    const double speeds[] = {1.0, 3.0, 5.0, 3.0};
    const double accelerations[] = {50.0, 50.0, -50.0, -50.0};
    for (int k = 0; k < 30; ++k)
      scenario.pieces.push_back({0.04, speeds[k % 4], accelerations[k % 4], (k % 2 == 0) ? 4.0 : -4.0});
  }
  if (speed == "rough")
    scenario.rough = RoughGround{};
  return scenario;
}

}  // namespace

std::shared_ptr<const Trajectory3> CloudScenario::trajectory() const {
  return makeTrajectory(start, pieces, rough);
}

std::vector<double> CloudScenario::sweepStartTimes() const {
  std::vector<double> times;
  const int sweeps = static_cast<int>(std::ceil(duration * lidar.rate - 1e-9));
  for (int k = 0; k < sweeps; ++k)
    times.push_back(k * lidar.sweepPeriod());
  return times;
}

std::vector<CloudScenario> cloudScenarios() {
  std::vector<CloudScenario> scenarios;
  for (const SpinningLidarModel& lidar : {SpinningLidarModel::vlp16(), SpinningLidarModel::os1_64()}) {
    scenarios.push_back(makeScenario(lidar, "static", "still"));
    for (const std::string speed : {"normal", "high"}) {
      scenarios.push_back(makeScenario(lidar, speed, "arc"));
      scenarios.push_back(makeScenario(lidar, speed, "turn"));
    }
    scenarios.push_back(makeScenario(lidar, "varying", "varying"));
    scenarios.push_back(makeScenario(lidar, "rough", "arc"));
  }
  return scenarios;
}

std::vector<CloudScenario> cloudSmoothScenarios() {
  std::vector<CloudScenario> scenarios;
  for (const SpinningLidarModel& lidar : {SpinningLidarModel::vlp16(), SpinningLidarModel::os1_64()}) {
    for (const std::string speed : {"normal", "high", "rough"})
      scenarios.push_back(makeScenario(lidar, speed, "smooth"));
  }
  return scenarios;
}

CloudScenario findCloudScenario(const std::string& name) {
  std::vector<CloudScenario> scenarios = cloudScenarios();
  for (CloudScenario& scenario : cloudSmoothScenarios())
    scenarios.push_back(std::move(scenario));
  return truth_text::findByName(scenarios, name, "cloud scenario");
}

std::shared_ptr<const Trajectory3> CloudTruth::trajectory() const {
  return makeTrajectory(start, pieces, rough);
}

Pose3 CloudTruth::sensorPoseAt(double t) const {
  return trajectory()->pose(t).compose(mount);
}

Pose3 CloudTruth::sensorPose(core::TimeNs time) const {
  return sensorPoseAt(core::nsToSeconds(time - epoch));
}

void writeCloudTruth(const CloudTruth& truth, const std::string& path) {
  std::ofstream out = truth_text::create(path, "lidar_deskew cloud simulation truth v1");
  out << "scenario " << truth.scenario << "\n";
  out << "world " << truth.world << "\n";
  out << "sensor " << truth.sensor << "\n";
  out << "convention " << truth.convention << "\n";
  out << "epoch_ns " << truth.epoch << "\n";
  out << "range_sigma " << truth.range_sigma << "\n";
  out << "mount";
  for (int i = 0; i < 3; ++i)
    out << " " << truth.mount.position[i];
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 3; ++column)
      out << " " << truth.mount.rotation(row, column);
  }
  out << "\n";
  truth_text::writeMotion(out, truth.start, truth.pieces);
  if (truth.rough) {
    const RoughGround& g = *truth.rough;
    out << "rough " << g.z_amplitude << " " << g.z_frequency << " " << g.pitch_amplitude << " "
        << g.pitch_frequency << " " << g.roll_amplitude << " " << g.roll_frequency << "\n";
  }
  for (const double time : truth.sweep_start_times)
    out << "sweep " << time << "\n";
  if (truth.odom_noise != 0.0 || truth.odom_yaw_scale != 1.0 || truth.odom_timing.any()) {
    truth_text::writeOdometry(out, truth.odom_noise, truth.odom_noise_seed, truth.odom_yaw_scale,
                              truth.odom_timing);
  }
  truth_text::finish(out, path);
}

CloudTruth readCloudTruth(const std::string& path) {
  CloudTruth truth;
  bool has_epoch = false, has_mount = false;
  const auto parse = [&](const std::string& key, std::istringstream& fields) {
    if (key == "scenario" || key == "world" || key == "sensor" || key == "convention") {
      std::string& value = key == "scenario" ? truth.scenario
                           : key == "world"  ? truth.world
                           : key == "sensor" ? truth.sensor
                                             : truth.convention;
      value = truth_text::rest(fields);
      return true;
    }
    if (key == "epoch_ns")
      return has_epoch = static_cast<bool>(fields >> truth.epoch);
    if (key == "range_sigma")
      return static_cast<bool>(fields >> truth.range_sigma);
    if (key == "mount") {
      has_mount = true;
      for (int i = 0; i < 3; ++i)
        has_mount = has_mount && static_cast<bool>(fields >> truth.mount.position[i]);
      for (int k = 0; k < 9; ++k)
        has_mount = has_mount && static_cast<bool>(fields >> truth.mount.rotation(k / 3, k % 3));
      return has_mount;
    }
    if (key == "rough") {
      truth.rough = RoughGround{};
      return static_cast<bool>(fields >> truth.rough->z_amplitude >> truth.rough->z_frequency >>
                               truth.rough->pitch_amplitude >> truth.rough->pitch_frequency >>
                               truth.rough->roll_amplitude >> truth.rough->roll_frequency);
    }
    if (key == "sweep") {
      double time;
      const bool ok = static_cast<bool>(fields >> time);
      truth.sweep_start_times.push_back(time);
      return ok;
    }
    if (truth_text::readOdometry(key, fields, &truth.odom_noise, &truth.odom_noise_seed,
                                 &truth.odom_yaw_scale, &truth.odom_timing))
      return true;
    return truth_text::readMotion(key, fields, &truth.start, &truth.pieces);
  };
  truth_text::readLines(path, [&](const std::string& key, std::istringstream& fields) {
    return parse(key, fields) && (fields >> std::ws).eof();  // nothing left over
  });
  if (!has_epoch || !has_mount || truth.pieces.empty() || truth.sensor.empty() || truth.world.empty()) {
    throw std::runtime_error(
        path + ": not a cloud truth file (needs epoch_ns, mount, piece, sensor and world lines)");
  }
  return truth;
}

}  // namespace lidar_deskew::sim
