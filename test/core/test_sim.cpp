// The simulator's own truth: closed-form motion against numerical integration, the truth file.
#include <gtest/gtest.h>

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
  EXPECT_EQ(scenarios.size(), 19u);  // 3 sensors x 3 motions x 2 speeds + varying
  EXPECT_EQ(findScenario("ILD26TRI/high/arc").lidar.beams, 360);
  EXPECT_THROW(findScenario("nope"), std::invalid_argument);
  // Every scenario's robot stays inside the hall, at least 0.5 m from any wall.
  const World hall = World::hall();
  for (const Scenario& scenario : scenarios) {
    const PiecewiseTrajectory trajectory = scenario.trajectory();
    for (double t = -0.1; t <= scenario.duration + 0.3; t += 0.01) {
      const Pose2 laser = trajectory.pose(t).compose(scenario.mount);
      EXPECT_GT(hall.distanceTo({laser.x, laser.y}), 0.5) << scenario.name << " at " << t;
    }
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
