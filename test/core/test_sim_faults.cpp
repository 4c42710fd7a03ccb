// The simulator's LaserScan timing faults (what deskew_calibrate estimates) against their definition,
// stated here again: stamp = true earliest beam + stamp_error; reversed: beam i truly measured at
// t0 + (n - 1 - i) dt while the message claims index order; time_increment = factor * true; scan_time
// 0. The truth file's timing lines; the LDS-01; the "turns" calibration drives stay inside their
// worlds with most beams returning.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

#include "lidar_deskew/sim/scenario.h"
#include "support/temporary.h"

namespace lidar_deskew::sim {
namespace {

constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;

/// The ILD26TRI (8 Hz, 360 beams) on an arc at 1.5 m/s and 2 rad/s in the demo room, laser off-centre:
/// every beam's pose differs, so a beam cast at the wrong time lands elsewhere.
struct Rig {
  World world = World::demoRoom();
  ArcTrajectory trajectory{{-1.0, 0.5, 0.3}, 1.5, 2.0};
  Pose2 mount{0.2, 0.05, 0.1};
  LidarModel model = LidarModel::ild26tri();
  double start_time = 0.4;

  SimulatedScan simulate(const TimingFault& fault) const {
    return simulateScan(world, trajectory, mount, model, kEpoch, start_time, nullptr, fault);
  }
  /// Range [m] of a ray cast from the laser's true pose at `t` [s] at `angle` [rad] in the laser frame.
  float rangeAt(double t, double angle) const {
    const Pose2 laser = trajectory.pose(t).compose(mount);
    const auto hit =
        world.castRay({laser.x, laser.y}, {std::cos(laser.yaw + angle), std::sin(laser.yaw + angle)});
    return hit && *hit <= model.range_max ? static_cast<float>(*hit) : std::numeric_limits<float>::infinity();
  }
};

double angleOf(const core::PlanarScan& scan, int i) {
  return static_cast<double>(scan.angle_min) + i * static_cast<double>(scan.angle_increment);
}

TEST(SimFaults, NoFaultIsTheDriverConvention) {
  const Rig rig;
  const SimulatedScan simulated = rig.simulate(TimingFault());
  EXPECT_FALSE(TimingFault().any());
  const core::PlanarScan& scan = simulated.scan;
  const double dt = static_cast<double>(rig.model.timeIncrement());
  EXPECT_EQ(scan.stamp, kEpoch + 400'000'000);
  EXPECT_EQ(scan.time_increment, rig.model.timeIncrement());
  EXPECT_EQ(scan.scan_time, 0.125f);
  ASSERT_EQ(simulated.beam_times.size(), 360u);
  for (int i = 0; i < 360; ++i) {
    EXPECT_NEAR(simulated.beam_times[i], 0.4 + i * dt, 1e-12);
    EXPECT_EQ(scan.ranges[i], rig.rangeAt(simulated.beam_times[i], angleOf(scan, i))) << i;
  }
}

TEST(SimFaults, StampErrorMovesOnlyTheStamp) {
  const Rig rig;
  const SimulatedScan truth = rig.simulate(TimingFault());
  const double sweep = 359 * static_cast<double>(rig.model.timeIncrement());
  EXPECT_DOUBLE_EQ(rig.model.sweepDuration(), sweep);
  EXPECT_DOUBLE_EQ(TimingFault::stampedAtEnd(rig.model).stamp_error, sweep);
  for (const double stamp_error : {-0.0123, 0.003, 0.25, sweep}) {
    TimingFault fault;
    fault.stamp_error = stamp_error;
    EXPECT_TRUE(fault.any());
    const SimulatedScan simulated = rig.simulate(fault);
    // stamp = true time of the earliest beam (beam 0) + stamp_error
    const double earliest = *std::min_element(simulated.beam_times.begin(), simulated.beam_times.end());
    EXPECT_EQ(earliest, simulated.beam_times[0]);
    EXPECT_NEAR(core::nsToSeconds(simulated.scan.stamp - kEpoch), earliest + stamp_error, 1e-9)
        << stamp_error;
    EXPECT_EQ(simulated.scan.stamp - truth.scan.stamp, core::secondsToNs(stamp_error));
    // The sensor measured what it measured: same beam times and ranges as without the fault.
    EXPECT_EQ(simulated.beam_times, truth.beam_times);
    EXPECT_EQ(simulated.scan.ranges, truth.scan.ranges);
    EXPECT_EQ(simulated.scan.time_increment, truth.scan.time_increment);
    EXPECT_EQ(simulated.scan.scan_time, truth.scan.scan_time);
  }
  // Stamped at the end: the stamp is the latest beam's true time.
  const SimulatedScan at_end = rig.simulate(TimingFault::stampedAtEnd(rig.model));
  EXPECT_NEAR(core::nsToSeconds(at_end.scan.stamp - kEpoch), at_end.beam_times.back(), 1e-9);
}

TEST(SimFaults, ReversedBeamsAreMeasuredLastToFirst) {
  const Rig rig;
  TimingFault fault;
  fault.reversed = true;
  fault.stamp_error = 0.01;
  const SimulatedScan simulated = rig.simulate(fault);
  const core::PlanarScan& scan = simulated.scan;
  const double dt = static_cast<double>(rig.model.timeIncrement());
  // The message claims index order, as an unfaulted one.
  EXPECT_GT(scan.time_increment, 0.0f);
  EXPECT_EQ(scan.time_increment, rig.model.timeIncrement());
  EXPECT_GT(scan.angle_increment, 0.0f);
  ASSERT_EQ(simulated.beam_times.size(), 360u);
  for (int i = 0; i < 360; ++i) {
    // beam i at t0 + (n - 1 - i) dt, cast from the laser's pose then, at the angle the message gives
    EXPECT_NEAR(simulated.beam_times[i], 0.4 + (359 - i) * dt, 1e-12) << i;
    if (i > 0) {
      EXPECT_LT(simulated.beam_times[i], simulated.beam_times[i - 1]);
    }
    EXPECT_EQ(scan.ranges[i], rig.rangeAt(simulated.beam_times[i], angleOf(scan, i))) << i;
  }
  // The earliest beam is index n - 1 and the stamp refers to it.
  EXPECT_NEAR(simulated.beam_times[359], 0.4, 1e-12);
  EXPECT_NEAR(core::nsToSeconds(scan.stamp - kEpoch), simulated.beam_times[359] + 0.01, 1e-9);
  // Moving, the reversed order measures other ranges; standing still, the same ones.
  const SimulatedScan in_order = rig.simulate(TimingFault());
  std::size_t differ = 0;
  for (int i = 0; i < 360; ++i)
    differ += scan.ranges[i] != in_order.scan.ranges[i];
  EXPECT_GT(differ, 300u);
  const ArcTrajectory still({-1.0, 0.5, 0.3}, 0.0, 0.0);
  const auto reversed_still =
      simulateScan(rig.world, still, rig.mount, rig.model, kEpoch, 0.4, nullptr, fault);
  const auto in_order_still = simulateScan(rig.world, still, rig.mount, rig.model, kEpoch, 0.4);
  EXPECT_EQ(reversed_still.scan.ranges, in_order_still.scan.ranges);
}

TEST(SimFaults, ReversedSpinAboutTheLaserInClosedForm) {
  // Spinning in place at w about the laser, beam i looks along w * t_i + angle_i in the world.
  const World world = World::smallRoom();
  const double w = 3.0;
  const ArcTrajectory spin({0.3, -0.2, 0.0}, 0.0, w);
  const LidarModel model = LidarModel::lds01();
  TimingFault fault;
  fault.reversed = true;
  const SimulatedScan simulated = simulateScan(world, spin, {}, model, kEpoch, 0.0, nullptr, fault);
  const double dt = static_cast<double>(model.timeIncrement());
  int returns = 0;
  for (int i = 0; i < model.beams; ++i) {
    const double direction = w * (model.beams - 1 - i) * dt + angleOf(simulated.scan, i);
    const auto hit = world.castRay({0.3, -0.2}, {std::cos(direction), std::sin(direction)});
    ASSERT_TRUE(hit);
    if (*hit <= model.range_max) {
      EXPECT_NEAR(simulated.scan.ranges[i], *hit, 1e-6) << i;
      ++returns;
    } else {
      EXPECT_EQ(simulated.scan.ranges[i], std::numeric_limits<float>::infinity()) << i;
    }
  }
  EXPECT_GT(returns, 300);
}

TEST(SimFaults, TimeIncrementFactorAndZeroScanTime) {
  const Rig rig;
  const SimulatedScan truth = rig.simulate(TimingFault());
  for (const double factor : {0.0, 0.5, 1.0, 2.0}) {
    TimingFault fault;
    fault.time_increment_factor = factor;
    const SimulatedScan simulated = rig.simulate(fault);
    EXPECT_EQ(simulated.scan.time_increment, static_cast<float>(factor * rig.model.timeIncrement()));
    EXPECT_EQ(simulated.scan.scan_time, 0.125f);
    EXPECT_EQ(simulated.beam_times, truth.beam_times);
    EXPECT_EQ(simulated.scan.ranges, truth.scan.ranges);
    EXPECT_EQ(simulated.scan.stamp, truth.scan.stamp);
  }
  TimingFault no_period;
  no_period.time_increment_factor = 0.0;
  no_period.zero_scan_time = true;
  const SimulatedScan simulated = rig.simulate(no_period);
  EXPECT_EQ(simulated.scan.time_increment, 0.0f);
  EXPECT_EQ(simulated.scan.scan_time, 0.0f);
  EXPECT_EQ(simulated.beam_times, truth.beam_times);
  EXPECT_EQ(simulated.scan.ranges, truth.scan.ranges);
}

TEST(SimFaults, InvalidFaultsAreRefusedNamingTheField) {
  const Rig rig;
  TimingFault fault;
  fault.stamp_error = std::nan("");
  try {
    rig.simulate(fault);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("stamp_error"), std::string::npos) << error.what();
  }
  for (const double factor : {-1.0, std::numeric_limits<double>::infinity()}) {
    fault = TimingFault();
    fault.time_increment_factor = factor;
    try {
      rig.simulate(fault);
      FAIL() << "expected an error";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("time_increment_factor"), std::string::npos) << error.what();
    }
  }
}

TEST(SimFaults, TruthFileRoundTripsTheFault) {
  Truth truth;
  truth.scenario = "LDS-01/high/turns";
  truth.epoch = kEpoch;
  truth.start = {-0.8, 0.0, 0.0};
  truth.pieces = {{1.0, 0.0, 0.0, 4.5}};
  truth.world = World::smallRoom();
  truth.timing_fault.stamp_error = 1.0 / 3.0;
  truth.timing_fault.reversed = true;
  truth.timing_fault.time_increment_factor = 0.0;
  truth.timing_fault.zero_scan_time = true;
  truth.beam_period = static_cast<double>(LidarModel::lds01().timeIncrement());
  truth.sweep_period = 0.2;
  EXPECT_EQ(truth.timeOffset(), -1.0 / 3.0);
  const std::string path = test::temporary("sim_faults", "truth");
  writeTruth(truth, path);
  Truth read = readTruth(path);
  EXPECT_EQ(read.timing_fault.stamp_error, 1.0 / 3.0);
  EXPECT_EQ(read.timeOffset(), -1.0 / 3.0);
  EXPECT_TRUE(read.timing_fault.reversed);
  EXPECT_EQ(read.timing_fault.time_increment_factor, 0.0);
  EXPECT_TRUE(read.timing_fault.zero_scan_time);
  EXPECT_EQ(read.beam_period, truth.beam_period);
  EXPECT_EQ(read.sweep_period, 0.2);
  // The lines as documented.
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* line : {"\nreversed 1\n", "\ntime_increment_factor 0\n", "\nzero_scan_time 1\n",
                           "\nsweep_period 0.20000000000000001\n", "\ntime_offset -0.33333333333333331\n"}) {
    EXPECT_NE(text.find(line), std::string::npos) << line << " in\n" << text;
  }

  // No fault: time_offset 0 (not -0), order as indexed.
  truth.timing_fault = TimingFault();
  writeTruth(truth, path);
  read = readTruth(path);
  EXPECT_FALSE(read.timing_fault.any());
  std::ifstream again(path);
  const std::string plain((std::istreambuf_iterator<char>(again)), std::istreambuf_iterator<char>());
  EXPECT_NE(plain.find("\ntime_offset 0\n"), std::string::npos) << plain;
  EXPECT_NE(plain.find("\nreversed 0\n"), std::string::npos) << plain;

  // A file from before faults existed reads as none, periods unknown.
  std::ofstream(path) << "# lidar_deskew simulation truth v1\nscenario X\nepoch_ns 5\nrange_sigma 0\n"
                         "mount 0 0 0\nstart 0 0 0\npiece 1 0 0 0\nwall 0 0 1 1\n";
  read = readTruth(path);
  EXPECT_FALSE(read.timing_fault.any());
  EXPECT_EQ(read.beam_period, 0.0);
  EXPECT_EQ(read.sweep_period, 0.0);
  // Flags are 0 or 1.
  std::ofstream(path) << "epoch_ns 5\npiece 1 0 0 0\nwall 0 0 1 1\nreversed 2\n";
  try {
    readTruth(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(":4:"), std::string::npos) << error.what();
  }
  std::remove(path.c_str());
}

TEST(SimFaults, TruthBeamTimeIsTheSimulatorsBeamTime) {
  const Rig rig;
  Truth truth;
  truth.epoch = kEpoch;
  truth.beam_period = static_cast<double>(rig.model.timeIncrement());
  for (const bool reversed : {false, true}) {
    truth.timing_fault.reversed = reversed;
    truth.timing_fault.stamp_error = -0.037;
    const SimulatedScan simulated = rig.simulate(truth.timing_fault);
    for (std::size_t i = 0; i < 360; ++i) {
      EXPECT_NEAR(core::nsToSeconds(truth.beamTime(simulated.scan.stamp, i, 360) - kEpoch),
                  simulated.beam_times[i], 1.5e-9)
          << reversed << " " << i;
    }
  }
}

TEST(SimFaults, Lds01) {
  const LidarModel lds = LidarModel::lds01();
  EXPECT_EQ(lds.name, "LDS-01");
  EXPECT_EQ(lds.beams, 360);
  EXPECT_EQ(lds.rate, 5.0);
  EXPECT_FALSE(lds.clockwise);
  EXPECT_NEAR(lds.angleIncrement(), M_PI / 180.0, 1e-7);        // 1 deg
  EXPECT_NEAR(lds.timeIncrement(), 0.2 / 360.0, 1e-9);          // 0.556 ms
  EXPECT_NEAR(lds.sweepDuration(), 359.0 * 0.2 / 360.0, 1e-7);  // 199.4 ms
  EXPECT_EQ(lds.range_min, 0.12f);
  EXPECT_EQ(lds.range_max, 3.5f);
  EXPECT_GE(lds.range_sigma, 0.010);
  EXPECT_LE(lds.range_sigma, 0.015);
}

TEST(SimFaults, SmallRoomOutline) {
  const World room = World::smallRoom();
  EXPECT_EQ(room.outline(), World::smallRoomOutline());
  EXPECT_TRUE(room.insideOutline({0.0, 0.0}));
  EXPECT_TRUE(room.insideOutline({2.4, 0.9}));
  EXPECT_FALSE(room.insideOutline({2.4, 1.9}));  // behind the cut corner
  EXPECT_FALSE(room.insideOutline({3.0, 0.0}));
  EXPECT_EQ(World::hall().outline(), World::hallOutline());
  EXPECT_TRUE(World::hall().insideOutline({5.0, 8.0}));  // in the corridor
  EXPECT_FALSE(World().insideOutline({0.0, 0.0}));
  // From the middle every wall is within the LDS-01's 3.5 m.
  const LidarModel lds = LidarModel::lds01();
  const SimulatedScan scan = simulateScan(room, ArcTrajectory({}, 0.0, 0.0), {}, lds, kEpoch, 0.0);
  for (float range : scan.scan.ranges)
    EXPECT_TRUE(std::isfinite(range));
}

TEST(SimFaults, CalibrationScenariosAreListedApart) {
  const std::vector<Scenario> calibration = calibrationScenarios();
  std::vector<std::string> names;
  for (const Scenario& scenario : calibration)
    names.push_back(scenario.name);
  EXPECT_EQ(names, (std::vector<std::string>{
                       "ILD26TRI/normal/turns", "ILD26TRI/high/turns", "UTM-30LX/normal/turns",
                       "UTM-30LX/high/turns", "UTM-30LX-270/normal/turns", "UTM-30LX-270/high/turns",
                       "LDS-01/normal/turns", "LDS-01/high/turns", "ILD26TRI/normal/spin",
                       "ILD26TRI/normal/circle", "UTM-30LX/normal/spin", "UTM-30LX/normal/circle",
                       "LDS-01/normal/spin", "LDS-01/normal/circle"}));
  EXPECT_EQ(paperScenarios().size(), 24u);
  for (const Scenario& scenario : paperScenarios())
    EXPECT_NE(scenario.motion, "turns") << scenario.name;
  EXPECT_EQ(planarScenarios().size(), 46u);  // the paper's 24, calibration's 14, the 8 smooth drives
  for (const std::string& name : names)
    EXPECT_EQ(findScenario(name).name, name);
  EXPECT_EQ(findScenario("LDS-01/high/turns").lidar.rate, 5.0);
  EXPECT_EQ(findScenario("LDS-01/high/turns").world.outline(), World::smallRoomOutline());
  EXPECT_EQ(findScenario("UTM-30LX/normal/turns").world.outline(), World::hallOutline());
}

/// The "turns" drives: long enough, turn rate changing every 1 to 2 s through standing still, turning
/// in place both ways, straight lines and arcs, within the speed class; the steady drives one constant
/// twist for 12 s (a spin in place, or a circle); for both, the laser inside the world's outline and
/// away from every wall at every 0.1 s of the recording (with its odometry margin); most beams of every
/// scan return.
TEST(SimFaults, TurnsScenariosStayInsideAndSeeTheWalls) {
  for (const Scenario& scenario : calibrationScenarios()) {
    SCOPED_TRACE(scenario.name);
    const bool high = scenario.speed == "high";
    const bool steady = scenario.motion != "turns";
    if (steady) {
      EXPECT_TRUE(scenario.motion == "spin" || scenario.motion == "circle");
      ASSERT_EQ(scenario.pieces.size(), 1u);
      EXPECT_EQ(scenario.pieces[0].acceleration, 0.0);
      EXPECT_NE(scenario.pieces[0].yaw_rate, 0.0);
      EXPECT_EQ(scenario.pieces[0].speed == 0.0, scenario.motion == "spin");
      EXPECT_EQ(scenario.duration, 12.0);
    }
    EXPECT_GE(scenario.duration, 12.0);
    double total = 0.0, max_speed = 0.0, max_turn = 0.0;
    bool still = false, left = false, right = false, straight = false, arc = false;
    for (std::size_t k = 0; k < scenario.pieces.size() && !steady; ++k) {
      const MotionPiece& piece = scenario.pieces[k];
      EXPECT_GE(piece.duration, 1.0 - 1e-12);
      EXPECT_LE(piece.duration, 2.0 + 1e-12);
      if (k > 0) {
        EXPECT_NE(piece.yaw_rate, scenario.pieces[k - 1].yaw_rate) << k;
      }
      total += piece.duration;
      max_speed = std::max(max_speed, std::abs(piece.speed) + std::abs(piece.acceleration) * piece.duration);
      max_turn = std::max(max_turn, std::abs(piece.yaw_rate));
      still |= piece.speed == 0.0 && piece.yaw_rate == 0.0;
      left |= piece.speed == 0.0 && piece.yaw_rate > 0.0;
      right |= piece.speed == 0.0 && piece.yaw_rate < 0.0;
      straight |= piece.speed > 0.0 && piece.yaw_rate == 0.0;
      arc |= piece.speed > 0.0 && piece.yaw_rate != 0.0;
    }
    if (!steady) {
      EXPECT_NEAR(total, scenario.duration, 1e-9);
      EXPECT_TRUE(still && left && right && straight && arc);
      EXPECT_EQ(scenario.pieces.back().speed, 0.0);  // goes on standing still
      EXPECT_EQ(scenario.pieces.back().yaw_rate, 0.0);
      EXPECT_LE(max_speed, high ? 2.0 : 1.0);
      EXPECT_LE(max_turn, high ? 5.0 : 2.0);
      EXPECT_GE(max_speed, high ? 1.5 : 0.8);
      EXPECT_GE(max_turn, high ? 4.0 : 2.0);
    }

    const PiecewiseTrajectory trajectory = scenario.trajectory();
    const double period = 1.0 / scenario.lidar.rate;
    double nearest = 1e9;
    for (int k = -1; k * 0.1 <= scenario.duration + period + 0.1 + 1e-9; ++k) {
      const double t = k * 0.1;
      const Pose2 base = trajectory.pose(t);
      const Pose2 laser = base.compose(scenario.mount);
      EXPECT_TRUE(scenario.world.insideOutline({laser.x, laser.y})) << t;
      EXPECT_TRUE(scenario.world.insideOutline({base.x, base.y})) << t;
      nearest = std::min(nearest, scenario.world.distanceTo({laser.x, laser.y}));
    }
    EXPECT_GT(nearest, 0.5);  // a robot's body fits

    // Every scan: the share of beams that return, and the turn rates scans are taken at.
    double worst = 1.0, sum = 0.0;
    int scans = 0;
    std::set<double> turn_rates;
    for (int k = 0; k * period < scenario.duration - 1e-9; ++k, ++scans) {
      const SimulatedScan simulated =
          simulateScan(scenario.world, trajectory, scenario.mount, scenario.lidar, kEpoch, k * period);
      const auto returns = std::count_if(simulated.scan.ranges.begin(), simulated.scan.ranges.end(),
                                         [](float range) { return std::isfinite(range); });
      const double share = static_cast<double>(returns) / simulated.scan.ranges.size();
      worst = std::min(worst, share);
      sum += share;
      turn_rates.insert(trajectory.yawRate(k * period + 0.5 * period));
    }
    const double mean = sum / scans;
    std::printf("%-26s %5.1f s %4d scans, nearest wall %.2f m, beams returning: mean %.3f, worst scan %.3f\n",
                scenario.name.c_str(), scenario.duration, scans, nearest, mean, worst);
    EXPECT_GT(worst, 0.75);
    EXPECT_GT(mean, 0.9);
    if (steady) {  // every scan at the same turn rate
      EXPECT_EQ(turn_rates.size(), 1u);
      continue;
    }
    // Scans at standing still, both turn directions and several rates.
    EXPECT_GE(turn_rates.size(), 6u);
    EXPECT_EQ(turn_rates.count(0.0), 1u);
    EXPECT_LT(*turn_rates.begin(), 0.0);
    EXPECT_GT(*turn_rates.rbegin(), 0.0);
  }
}

}  // namespace
}  // namespace lidar_deskew::sim
