#include "lidar_deskew/sim/scenario.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "truth_text.h"

namespace lidar_deskew::sim {
namespace {

/// [s] The smooth drives: one period of the turn rate.
constexpr double kSmoothDuration = 1.3;

/// A "0" or "1" field into `flag`: whether it was one of them.
bool readFlag(std::istream& fields, bool* flag) {
  int value = -1;
  fields >> value;
  *flag = value == 1;
  return value == 0 || value == 1;
}

Scenario makeScenario(const LidarModel& lidar, const std::string& speed, const std::string& motion) {
  Scenario scenario;
  scenario.lidar = lidar;
  scenario.speed = speed;
  scenario.motion = motion;
  scenario.name = lidar.name + "/" + speed + "/" + motion;
  const bool high = speed == "high";
  const double v = high ? 6.0 : 1.5;
  const double w = high ? 5.0 : 2.0;
  if (lidar.range_max < 10.0f) {
    // The LDS-01 reaches 3.5 m: World::smallRoom(), the laser 32 mm behind the base (TurtleBot3
    // Burger), 8 scans. A line from the west half (3 m at normal speed with the odometry margins), a
    // spin in the middle, an arc on a circle about the middle (radius v / w: 0.75 m, 1.2 m).
    scenario.world = World::smallRoom();
    scenario.mount = {-0.032, 0.0, 0.0};
    scenario.duration = 8.0 / lidar.rate;
    if (motion == "translation")
      scenario.start = {-1.5, -0.4, 0.0};
    else if (motion == "rotation")
      scenario.start = {0.0, 0.0, 0.0};
    else
      scenario.start = {0.0, -v / w, 0.0};
  } else {
    // The paper mounts the laser off the rotation centre for the high-speed case.
    scenario.mount = high ? Pose2{0.25, 0.05, 0.1} : Pose2{0.0, 0.0, 0.0};
    scenario.start = {-10.0, 0.5, 0.0};
    // About 8 scans for the 8 Hz sensor, 20 for the 40 Hz ones.
    scenario.duration = lidar.rate < 20.0 ? 1.0 : 0.5;
  }
  if (motion == "translation") {
    scenario.pieces = {{scenario.duration, v, 0.0, 0.0}};
  } else if (motion == "rotation") {
    scenario.pieces = {{scenario.duration, 0.0, 0.0, w}};
  } else {
    scenario.pieces = {{scenario.duration, v, 0.0, w}};
  }
  return scenario;
}

/// The "turns" drives: (duration, speed, acceleration, yaw rate) pieces of 1 to 2 s, each a multiple
/// of 0.1 s so that the changes fall on 50 Hz odometry samples (tf interpolates linearly between
/// samples and could not follow a change between them). The turn rate changes at every piece; both
/// end standing still, so the last piece going on past the end keeps the robot where it is.
std::vector<MotionPiece> turnsPieces(bool high) {
  if (!high) {  // 14.7 s, up to 1 m/s and 2 rad/s
    return {{1.0, 0.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 1.5}, {1.0, 0.6, 0.0, 0.0},  {1.5, 0.0, 0.0, -2.0},
            {1.5, 0.8, 0.0, 1.6}, {1.0, 0.0, 0.0, 0.0}, {2.0, 0.0, 0.0, -1.0}, {1.5, 1.0, 0.0, -2.0},
            {1.0, 0.0, 0.0, 2.0}, {1.2, 0.5, 0.0, 0.0}, {1.0, 0.3, 0.0, -0.5}, {1.0, 0.0, 0.0, 0.0}};
  }
  // 13.5 s, up to 2 m/s and 5 rad/s
  return {{1.0, 0.0, 0.0, 0.0},  {1.0, 0.0, 0.0, 4.5}, {1.5, 2.0, 0.0, -4.0}, {1.0, 0.0, 0.0, -5.0},
          {1.0, 0.0, 0.0, 0.0},  {1.0, 1.5, 0.0, 0.5}, {1.0, 0.0, 0.0, 3.0},  {1.5, 2.0, 0.0, 4.0},
          {1.5, 0.0, 0.0, -4.0}, {1.0, 1.0, 0.0, 0.0}, {1.0, 1.0, 0.0, -2.0}, {1.0, 0.0, 0.0, 0.0}};
}

Scenario makeTurnsScenario(const LidarModel& lidar, const std::string& speed) {
  Scenario scenario;
  scenario.lidar = lidar;
  scenario.speed = speed;
  scenario.motion = "turns";
  scenario.name = lidar.name + "/" + speed + "/turns";
  const bool high = speed == "high";
  scenario.pieces = turnsPieces(high);
  scenario.duration = 0.0;
  for (const MotionPiece& piece : scenario.pieces)
    scenario.duration += piece.duration;
  if (lidar.range_max < 10.0f) {
    // The LDS-01 reaches 3.5 m: a small room, the laser 32 mm behind the base (TurtleBot3 Burger).
    scenario.world = World::smallRoom();
    scenario.mount = {-0.032, 0.0, 0.0};
    scenario.start = high ? Pose2{-0.8, 0.0, 0.0} : Pose2{-0.3, -0.3, 0.0};
  } else {
    // The hall, where the paper's scenarios start; the mount of the paper's speed.
    scenario.mount = high ? Pose2{0.25, 0.05, 0.1} : Pose2{0.0, 0.0, 0.0};
    scenario.start = {-10.0, 0.5, 0.0};
  }
  return scenario;
}

/// A steady drive for timing calibration: one constant twist for 12 s, turning in place ("spin") or
/// on one circle ("circle"). A constant offset moves every scan of it by the same rigid transform:
/// the beam order and the period show, the offset does not.
Scenario makeSteadyScenario(const LidarModel& lidar, const std::string& motion) {
  Scenario scenario = makeTurnsScenario(lidar, "normal");
  scenario.motion = motion;
  scenario.name = lidar.name + "/normal/" + motion;
  scenario.duration = 12.0;
  const bool spin = motion == "spin";
  const double v = spin ? 0.0 : 0.5, w = spin ? 1.5 : 1.0;  // a circle of 0.5 m radius
  scenario.pieces = {{scenario.duration, v, 0.0, w}};
  scenario.start = lidar.range_max < 10.0f ? Pose2{0.0, spin ? 0.0 : -v / w, 0.0} : Pose2{-10.0, 0.5, 0.0};
  return scenario;
}

/// Motion whose twist changes between samples (smoothUnicyclePieces): "normal" 1.5 m/s and 2 rad/s,
/// "high" 6 m/s and 5 rad/s at their peaks, the laser 0.25 m ahead, 0.05 m left and turned 0.1 rad.
Scenario makeSmoothScenario(const LidarModel& lidar, const std::string& speed) {
  Scenario scenario;
  scenario.lidar = lidar;
  scenario.speed = speed;
  scenario.motion = "smooth";
  scenario.name = lidar.name + "/" + speed + "/smooth";
  const bool high = speed == "high";
  scenario.mount = {0.25, 0.05, 0.1};
  scenario.duration = kSmoothDuration;
  if (lidar.range_max < 10.0f) {
    // In the small room the laser stays 0.3 m inside the walls (1.5 m/s: within 0.7 m of the start).
    scenario.world = World::smallRoom();
    scenario.start = high ? Pose2{-0.2, -1.6, 0.0} : Pose2{0.0, -0.2, 0.0};
  } else {
    scenario.start = {-10.0, -1.5, 0.0};
  }
  // Pieces to well past the last scan and the odometry's margin; the last one goes on after that.
  scenario.pieces = smoothUnicyclePieces(high ? 6.0 : 1.5, high ? 5.0 : 2.0, kSmoothDuration + 1.0);
  return scenario;
}

}  // namespace

std::vector<Scenario> smoothScenarios() {
  std::vector<Scenario> scenarios;
  for (const std::string speed : {"normal", "high"}) {
    for (const LidarModel& lidar :
         {LidarModel::utm30lx360(), LidarModel::ild26tri(), LidarModel::utm30lx270(), LidarModel::lds01()})
      scenarios.push_back(makeSmoothScenario(lidar, speed));
  }
  return scenarios;
}

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
  // The LDS-01 in the small room, after the paper's: every motion that fits 8 scans (1.6 s) in 5 x 4 m.
  // At 6 m/s a straight line would need 12 m with the odometry margins: no LDS-01/high/translation.
  const LidarModel lds01 = LidarModel::lds01();
  for (const std::string motion : {"translation", "rotation", "arc"})
    scenarios.push_back(makeScenario(lds01, "normal", motion));
  for (const std::string motion : {"rotation", "arc"})
    scenarios.push_back(makeScenario(lds01, "high", motion));
  return scenarios;
}

std::vector<Scenario> calibrationScenarios() {
  std::vector<Scenario> scenarios;
  for (const LidarModel& lidar :
       {LidarModel::ild26tri(), LidarModel::utm30lx360(), LidarModel::utm30lx270(), LidarModel::lds01()}) {
    for (const std::string speed : {"normal", "high"})
      scenarios.push_back(makeTurnsScenario(lidar, speed));
  }
  for (const LidarModel& lidar : {LidarModel::ild26tri(), LidarModel::utm30lx360(), LidarModel::lds01()}) {
    for (const std::string motion : {"spin", "circle"})
      scenarios.push_back(makeSteadyScenario(lidar, motion));
  }
  return scenarios;
}

Scenario turnsScenario(const LidarModel& lidar, const std::string& speed) {
  return makeTurnsScenario(lidar, speed);
}

std::vector<Scenario> planarScenarios() {
  std::vector<Scenario> scenarios = paperScenarios();
  for (Scenario& scenario : calibrationScenarios())
    scenarios.push_back(std::move(scenario));
  for (Scenario& scenario : smoothScenarios())
    scenarios.push_back(std::move(scenario));
  return scenarios;
}

Scenario findScenario(const std::string& name) {
  return truth_text::findByName(planarScenarios(), name, "scenario");
}

Scenario clockwiseVariant(Scenario scenario) {
  scenario.lidar.clockwise = true;
  scenario.name += "/clockwise";
  return scenario;
}

Pose2 Truth::mountAt(core::TimeNs time) const {
  return mount_change && core::nsToSeconds(time - epoch) >= mount_change->time ? mount_change->mount : mount;
}

Pose2 Truth::laserPose(core::TimeNs time) const {
  return trajectory().pose(core::nsToSeconds(time - epoch)).compose(mountAt(time));
}

core::TimeNs Truth::beamTime(core::TimeNs stamp, std::size_t index, std::size_t beams) const {
  const std::size_t order = timing_fault.reversed ? beams - 1 - index : index;  // place in time
  // As simulateScan: the earliest beam's ns time, plus whole beam periods.
  const core::TimeNs earliest = stamp - core::secondsToNs(timing_fault.stamp_error);
  return earliest + core::secondsToNs(static_cast<double>(order) * beam_period);
}

void writeTruth(const Truth& truth, const std::string& path) {
  std::ofstream out = truth_text::create(path, "lidar_deskew simulation truth v1");
  out << "scenario " << truth.scenario << "\n";
  out << "epoch_ns " << truth.epoch << "\n";
  out << "range_sigma " << truth.range_sigma << "\n";
  out << "mount " << truth.mount.x << " " << truth.mount.y << " " << truth.mount.yaw << "\n";
  if (const auto& change = truth.mount_change) {
    out << "mount_change " << change->time << " " << change->mount.x << " " << change->mount.y << " "
        << change->mount.yaw << "\n";
  }
  out << "time_offset " << truth.timeOffset() << "\n";
  out << "reversed " << (truth.timing_fault.reversed ? 1 : 0) << "\n";
  out << "time_increment_factor " << truth.timing_fault.time_increment_factor << "\n";
  out << "zero_scan_time " << (truth.timing_fault.zero_scan_time ? 1 : 0) << "\n";
  out << "beam_period " << truth.beam_period << "\n";
  out << "sweep_period " << truth.sweep_period << "\n";
  truth_text::writeOdometry(out, truth.odom_noise, truth.odom_noise_seed, truth.odom_yaw_scale,
                            truth.odom_timing);
  truth_text::writeMotion(out, truth.start, truth.pieces);
  for (const Segment& segment : truth.world.segments()) {
    out << "wall " << segment.a.x() << " " << segment.a.y() << " " << segment.b.x() << " " << segment.b.y()
        << "\n";
  }
  truth_text::finish(out, path);
}

void OdometryTiming::validate() const {
  const auto check = [](double value, const char* name) {
    if (!(value >= 0.0) || !std::isfinite(value))
      throw std::invalid_argument(std::string("odometry ") + name + ": must be finite and >= 0");
  };
  check(jitter, "jitter");
  check(rate_min, "rate_min");
  check(rate_max, "rate_max");
  check(tick, "tick");
  check(wheel_base, "wheel_base");
  check(late, "late");
  if ((rate_min == 0.0) != (rate_max == 0.0) || rate_min > rate_max)
    throw std::invalid_argument("odometry rate: give 0 < LO <= HI Hz (or neither)");
  if (tick > 0.0 && !(wheel_base > 0.0))
    throw std::invalid_argument("odometry ticks: need a wheel base > 0 m");
  if (burst < 1)
    throw std::invalid_argument("odometry burst: must be >= 1 sample");
}

std::vector<OdometrySample> recordOdometry(const PiecewiseTrajectory& truth, double begin, long last,
                                           double end, double rate, double noise, unsigned seed,
                                           double yaw_scale, const OdometryTiming& timing) {
  timing.validate();
  // The samples' true times: the grid (jitter further out at each end), or irregular.
  std::seed_seq timing_seed{seed, 0x0d0e7u};  // apart from the noise's generator
  std::mt19937 timing_rng(timing_seed);
  std::vector<double> times;
  if (timing.rate_min > 0.0) {
    std::uniform_real_distribution<double> interval(1.0 / timing.rate_max, 1.0 / timing.rate_min);
    times.push_back(begin - timing.jitter);
    while (times.back() < end + timing.jitter)
      times.push_back(times.back() + interval(timing_rng));
  } else {
    const long extra = std::lround(std::ceil(timing.jitter * rate - 1e-9));
    for (long k = -extra; k <= last + extra; ++k)
      times.push_back(begin + static_cast<double>(k) / rate);
  }
  // What the odometry reports, in 20 ms steps from the first sample (throws for a bad noise).
  const NoisyOdometry odometry(truth, times.front(), std::max(end, times.back()), noise, seed, yaw_scale);
  const std::size_t n = times.size();
  std::vector<OdometrySample> samples(n);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = times[i];
    OdometrySample& sample = samples[i];
    sample.time = t;
    sample.stamp = t + (timing.jitter > 0.0 ? timing.jitter * unit(timing_rng) : 0.0);
    sample.record = sample.stamp + timing.late;
    sample.pose = odometry.pose(t);
    const NoisyOdometry::Factors factors = odometry.factors(t);
    sample.speed = truth.speed(t) * factors.x;
    sample.yaw_rate = truth.yawRate(t) * factors.yaw;
  }
  if (timing.tick > 0.0) {
    // A differential drive's encoders: each wheel's travel along the odometry's motion, counted in whole
    // ticks from a random phase; the pose integrated from each interval's counts, exactly along an arc.
    const double tick = timing.tick, half_base = 0.5 * timing.wheel_base;
    const auto sinc = [](double x) { return std::abs(x) < 1e-9 ? 1.0 : std::sin(x) / x; };
    std::uniform_real_distribution<double> phase(0.0, tick);
    double left = phase(timing_rng), right = phase(timing_rng);  // [m] continuous wheel travel
    double left_ticks = std::floor(left / tick), right_ticks = std::floor(right / tick);
    Pose2 pose = samples[0].pose;
    for (std::size_t i = 1; i < n; ++i) {
      const Pose2 step = odometry.pose(times[i - 1]).between(samples[i].pose);
      const double arc = std::copysign(std::hypot(step.x, step.y), step.x) / sinc(0.5 * step.yaw);
      left += arc - half_base * step.yaw;
      right += arc + half_base * step.yaw;
      const double new_left = std::floor(left / tick), new_right = std::floor(right / tick);
      const double ds = 0.5 * tick * ((new_left - left_ticks) + (new_right - right_ticks));
      const double dyaw = tick * ((new_right - right_ticks) - (new_left - left_ticks)) / timing.wheel_base;
      left_ticks = new_left;
      right_ticks = new_right;
      const double chord = ds * sinc(0.5 * dyaw);
      pose = pose.compose({chord * std::cos(0.5 * dyaw), chord * std::sin(0.5 * dyaw), dyaw});
      samples[i].pose = pose;
      const double dt = times[i] - times[i - 1];
      samples[i].speed = ds / dt;
      samples[i].yaw_rate = dyaw / dt;
    }
    samples[0].speed = n > 1 ? samples[1].speed : 0.0;
    samples[0].yaw_rate = n > 1 ? samples[1].yaw_rate : 0.0;
  }
  // Bursts: every `burst` samples recorded together, at the last one's record time.
  for (std::size_t first = 0; first < n; first += static_cast<std::size_t>(timing.burst)) {
    const std::size_t burst_last = std::min(n, first + static_cast<std::size_t>(timing.burst)) - 1;
    for (std::size_t i = first; i < burst_last; ++i)
      samples[i].record = samples[burst_last].record;
  }
  std::stable_sort(samples.begin(), samples.end(),
                   [](const OdometrySample& a, const OdometrySample& b) { return a.record < b.record; });
  return samples;
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
    if (key == "mount_change") {
      truth.mount_change.emplace();
      return static_cast<bool>(fields >> truth.mount_change->time >> truth.mount_change->mount.x >>
                               truth.mount_change->mount.y >> truth.mount_change->mount.yaw);
    }
    if (key == "time_offset") {
      double time_offset;
      const bool ok = static_cast<bool>(fields >> time_offset);
      truth.timing_fault.stamp_error = 0.0 - time_offset;
      return ok;
    }
    if (key == "reversed")
      return readFlag(fields, &truth.timing_fault.reversed);
    if (key == "time_increment_factor")
      return static_cast<bool>(fields >> truth.timing_fault.time_increment_factor);
    if (key == "zero_scan_time")
      return readFlag(fields, &truth.timing_fault.zero_scan_time);
    if (key == "beam_period")
      return static_cast<bool>(fields >> truth.beam_period);
    if (key == "sweep_period")
      return static_cast<bool>(fields >> truth.sweep_period);
    if (truth_text::readOdometry(key, fields, &truth.odom_noise, &truth.odom_noise_seed,
                                 &truth.odom_yaw_scale, &truth.odom_timing))
      return true;
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
