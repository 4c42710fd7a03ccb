// The simulator's own truth: closed-form motion against numerical integration, the truth file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::sim {
namespace {

/// x, y of a unicycle by Simpson's rule over `steps` intervals (heading is exact: start.yaw + w t).
Eigen::Vector2d integrateNumerically(const Pose2& start, double speed, double acceleration, double yaw_rate,
                                     double t, int steps) {
  const double h = t / steps;
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int i = 0; i <= steps; ++i) {
    const double s = i * h;
    const double weight = (i == 0 || i == steps) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    const double heading = start.yaw + yaw_rate * s;
    sum += weight * (speed + acceleration * s) * Eigen::Vector2d(std::cos(heading), std::sin(heading));
  }
  return Eigen::Vector2d(start.x, start.y) + sum * h / 3.0;
}

TEST(Sim, UnicycleClosedFormMatchesNumericalIntegration) {
  const Pose2 start{1.0, -2.0, 0.7};
  for (const auto& [speed, acceleration, yaw_rate] : std::vector<std::tuple<double, double, double>>{
           {6.0, 0.0, 5.0}, {1.0, 32.0, -4.0}, {2.0, -3.0, 0.0}, {0.0, 0.0, 2.0}}) {
    for (const double t : {0.01, 0.125, 1.3}) {
      const Pose2 closed = integrateUnicycle(start, speed, acceleration, yaw_rate, t);
      const Eigen::Vector2d numeric = integrateNumerically(start, speed, acceleration, yaw_rate, t, 20000);
      EXPECT_NEAR(closed.x, numeric.x(), 1e-9) << speed << " " << acceleration << " " << yaw_rate << " " << t;
      EXPECT_NEAR(closed.y, numeric.y(), 1e-9);
      EXPECT_NEAR(closed.yaw, start.yaw + yaw_rate * t, 1e-15);
    }
  }
}

TEST(Sim, PiecewiseMotionIsContinuousAndFollowsItsPieces) {
  const PiecewiseTrajectory trajectory({0.0, 0.0, 0.0}, {{0.5, 1.0, 2.0, 1.0}, {0.5, 2.0, 0.0, -1.0}});
  const Pose2 before = trajectory.pose(0.5 - 1e-12), after = trajectory.pose(0.5);
  EXPECT_NEAR(before.x, after.x, 1e-9);
  EXPECT_NEAR(before.y, after.y, 1e-9);
  EXPECT_NEAR(before.yaw, after.yaw, 1e-9);
  EXPECT_NEAR(trajectory.speed(0.25), 1.5, 1e-12);
  EXPECT_NEAR(trajectory.speed(0.75), 2.0, 1e-12);
  EXPECT_EQ(trajectory.yawRate(0.75), -1.0);
  const Pose2 end = trajectory.pose(1.0);
  const Pose2 expected =
      integrateUnicycle(integrateUnicycle({0, 0, 0}, 1.0, 2.0, 1.0, 0.5), 2.0, 0.0, -1.0, 0.5);
  EXPECT_NEAR(end.x, expected.x, 1e-12);
  EXPECT_NEAR(end.y, expected.y, 1e-12);
}

TEST(Sim, PaperScenariosAreAllThere) {
  const auto scenarios = paperScenarios();
  // 3 sensors x 3 motions x 2 speeds + varying, then the LDS-01's five
  ASSERT_EQ(scenarios.size(), 24u);
  EXPECT_EQ(findScenario("ILD26TRI/high/arc").lidar.beams, 360);
  EXPECT_THROW(findScenario("nope"), std::invalid_argument);
  EXPECT_EQ(scenarios[18].name, "ILD26TRI/varying/varying");
  std::vector<std::string> lds01;
  for (std::size_t k = 19; k < scenarios.size(); ++k)
    lds01.push_back(scenarios[k].name);
  EXPECT_EQ(lds01,
            (std::vector<std::string>{"LDS-01/normal/translation", "LDS-01/normal/rotation",
                                      "LDS-01/normal/arc", "LDS-01/high/rotation", "LDS-01/high/arc"}));
  // Every scenario's laser stays inside its world, at least 0.5 m from any wall of the hall or 0.3 m from
  // any wall of the small room, over the bag's odometry (0.1 s margins) and beyond.
  for (const Scenario& scenario : scenarios) {
    const bool small_room = scenario.lidar.name == "LDS-01";
    EXPECT_EQ(scenario.world.outline(), small_room ? World::smallRoomOutline() : World::hallOutline())
        << scenario.name;
    const PiecewiseTrajectory trajectory = scenario.trajectory();
    const double end = scenario.duration + std::max(0.3, 1.0 / scenario.lidar.rate + 0.1);
    for (double t = -0.1; t <= end; t += 0.01) {
      const Pose2 base = trajectory.pose(t);
      const Pose2 laser = base.compose(scenario.mount);
      EXPECT_TRUE(scenario.world.insideOutline({base.x, base.y})) << scenario.name << " at " << t;
      EXPECT_GT(scenario.world.distanceTo({laser.x, laser.y}), small_room ? 0.3 : 0.5)
          << scenario.name << " at " << t;
    }
  }
}

/// The LDS-01 paper scenarios: 8 scans at the paper's speeds (normal 1.5 m/s, 2 rad/s; high 6 m/s,
/// 5 rad/s), the TurtleBot3's mount, and most beams of every scan return from a wall within 3.5 m.
TEST(Sim, Lds01PaperScenariosSeeTheWallsInEveryScan) {
  for (const char* name : {"LDS-01/normal/translation", "LDS-01/normal/rotation", "LDS-01/normal/arc",
                           "LDS-01/high/rotation", "LDS-01/high/arc"}) {
    const Scenario scenario = findScenario(name);
    SCOPED_TRACE(name);
    const bool high = scenario.speed == "high";
    EXPECT_EQ(scenario.lidar.range_max, 3.5f);
    EXPECT_EQ(scenario.mount.x, -0.032);
    ASSERT_EQ(scenario.pieces.size(), 1u);
    const MotionPiece& piece = scenario.pieces[0];
    EXPECT_EQ(piece.speed, scenario.motion == "rotation" ? 0.0 : (high ? 6.0 : 1.5));
    EXPECT_EQ(piece.yaw_rate, scenario.motion == "translation" ? 0.0 : (high ? 5.0 : 2.0));
    const PiecewiseTrajectory trajectory = scenario.trajectory();
    const double period = 1.0 / scenario.lidar.rate;
    int scans = 0;
    double worst = 1.0;
    for (; scans * period < scenario.duration - 1e-9; ++scans) {
      const SimulatedScan simulated =
          simulateScan(scenario.world, trajectory, scenario.mount, scenario.lidar, 0, scans * period);
      const auto returns = std::count_if(simulated.scan.ranges.begin(), simulated.scan.ranges.end(),
                                         [](float range) { return std::isfinite(range); });
      worst = std::min(worst, static_cast<double>(returns) / simulated.scan.ranges.size());
    }
    std::printf("%-26s %d scans, worst scan %.3f of its beams returning\n", name, scans, worst);
    EXPECT_EQ(scans, 8);
    EXPECT_GT(worst, 0.75);
  }
}

TEST(Sim, TruthFileRoundTripsExactly) {
  Truth truth;
  truth.scenario = "ILD26TRI/varying/varying";
  truth.epoch = 1'700'000'000'123'456'789;
  truth.range_sigma = 0.06;
  truth.mount = {0.25, 0.05, 0.1};
  truth.start = {-10.0, 0.5, 1.0 / 3.0};
  truth.pieces = {{0.0625, 1.0, 32.0, 4.0}, {0.0625, 3.0, 32.0, -4.0}};
  truth.world = World::hall();
  const std::string path = ::testing::TempDir() + "/roundtrip.truth";
  writeTruth(truth, path);
  const Truth read = readTruth(path);
  EXPECT_EQ(read.scenario, truth.scenario);
  EXPECT_EQ(read.epoch, truth.epoch);
  EXPECT_EQ(read.range_sigma, truth.range_sigma);
  EXPECT_EQ(read.start.yaw, truth.start.yaw);
  ASSERT_EQ(read.pieces.size(), 2u);
  EXPECT_EQ(read.pieces[1].yaw_rate, -4.0);
  ASSERT_EQ(read.world.segments().size(), truth.world.segments().size());
  const Pose2 a = truth.laserPose(truth.epoch + 100'000'000), b = read.laserPose(truth.epoch + 100'000'000);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);

  std::ofstream(path) << "epoch_ns 5\npiece 1 2 3\n";
  try {
    readTruth(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(":2:"), std::string::npos) << error.what();
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace lidar_deskew::sim
