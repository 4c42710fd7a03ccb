// The simulator's own truth: closed-form motion against numerical integration, the truth file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "lidar_deskew/sim/scenario.h"
#include "support/temporary.h"

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

/// Every scenario's laser stays inside its world, at least 0.5 m from any wall of the hall or 0.3 m from
/// any wall of the small room, over the bag's odometry (0.1 s margins) and beyond.
void expectInsideTheirWorlds(const std::vector<Scenario>& scenarios) {
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
  expectInsideTheirWorlds(scenarios);
}

/// Speed 6 cos(2 pi t / 2) m/s, turn rate 5 cos(2 pi t / 1.3) rad/s, from (1, -2, 0.3): the pieces follow
/// the smooth unicycle, integrated here independently by the classical Runge-Kutta method in 10 us steps
/// (error ~1e-13 m), to 2 um over 2 s; the speed and turn rate at a piece's start are the cosines'.
TEST(Sim, SmoothUnicyclePiecesFollowTheCosines) {
  const double speed = 6.0, yaw_rate = 5.0, duration = 2.0;
  const PiecewiseTrajectory trajectory({1.0, -2.0, 0.3}, smoothUnicyclePieces(speed, yaw_rate, duration));
  EXPECT_EQ(trajectory.pieces().size(), 8000u);
  const auto derivative = [&](double t, const Eigen::Vector3d& state) {
    const double v = speed * std::cos(M_PI * t);
    return Eigen::Vector3d(v * std::cos(state.z()), v * std::sin(state.z()),
                           yaw_rate * std::cos(2.0 * M_PI * t / 1.3));
  };
  Eigen::Vector3d state(1.0, -2.0, 0.3);
  const double h = 1e-5;
  double worst_position = 0.0, worst_heading = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const double t = i * h;
    if (i % 1000 == 0) {
      const Pose2 pose = trajectory.pose(t);
      worst_position = std::max(worst_position, std::hypot(pose.x - state.x(), pose.y - state.y()));
      worst_heading = std::max(worst_heading, std::abs(pose.yaw - state.z()));
      EXPECT_NEAR(trajectory.speed(t), speed * std::cos(M_PI * t), 1e-6 * speed) << t;
    }
    const Eigen::Vector3d k1 = derivative(t, state), k2 = derivative(t + h / 2, state + h / 2 * k1);
    const Eigen::Vector3d k3 = derivative(t + h / 2, state + h / 2 * k2),
                          k4 = derivative(t + h, state + h * k3);
    state += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  std::printf("smooth unicycle pieces vs Runge-Kutta: %.2e m, %.2e rad\n", worst_position, worst_heading);
  EXPECT_LT(worst_position, 2e-6);
  EXPECT_LT(worst_heading, 1e-9);
}

TEST(Sim, SmoothScenariosAreAllThere) {
  const auto scenarios = smoothScenarios();
  ASSERT_EQ(scenarios.size(), 8u);
  EXPECT_EQ(scenarios.front().name, "UTM-30LX/normal/smooth");
  EXPECT_EQ(scenarios.back().name, "LDS-01/high/smooth");
  EXPECT_EQ(findScenario("ILD26TRI/high/smooth").pieces.front().speed, 6.0);
  EXPECT_EQ(findScenario("LDS-01/normal/smooth").pieces.front().speed, 1.5);
  expectInsideTheirWorlds(scenarios);
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
  truth.odom_noise = 0.1;
  truth.odom_noise_seed = 4'000'000'007u;
  const std::string path = test::temporary("sim", "roundtrip.truth");
  writeTruth(truth, path);
  const Truth read = readTruth(path);
  EXPECT_EQ(read.odom_noise, 0.1);
  EXPECT_EQ(read.odom_noise_seed, 4'000'000'007u);
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

  // A file from before odometry noise: perfect odometry.
  std::ofstream(path) << "epoch_ns 5\nstart 0 0 0\npiece 1 2 0 3\nwall 0 0 1 1\n";
  EXPECT_EQ(readTruth(path).odom_noise, 0.0);
  EXPECT_EQ(readTruth(path).odom_noise_seed, 0u);

  std::ofstream(path) << "epoch_ns 5\npiece 1 2 3\n";
  try {
    readTruth(path);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(":2:"), std::string::npos) << error.what();
  }
  std::remove(path.c_str());
}

/// The test's own relative pose: `later` in `earlier`'s frame (x, y [m], yaw [rad]).
Eigen::Vector3d relative(const Pose2& earlier, const Pose2& later) {
  const double c = std::cos(earlier.yaw), s = std::sin(earlier.yaw);
  const double dx = later.x - earlier.x, dy = later.y - earlier.y;
  return {c * dx + s * dy, -s * dx + c * dy, later.yaw - earlier.yaw};
}

/// The test's own composition: `pose` followed by the relative pose `step`.
Pose2 composed(const Pose2& pose, const Eigen::Vector3d& step) {
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  return {pose.x + c * step.x() - s * step.y(), pose.y + s * step.x() + c * step.y(), pose.yaw + step.z()};
}

struct Moments {
  double mean = 0.0;
  double std = 0.0;
};
Moments moments(const std::vector<double>& values) {
  Moments m;
  for (double v : values)
    m.mean += v / values.size();
  for (double v : values)
    m.std += (v - m.mean) * (v - m.mean) / (values.size() - 1);
  m.std = std::sqrt(m.std);
  return m;
}
double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const Moments ma = moments(a), mb = moments(b);
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    sum += (a[i] - ma.mean) * (b[i] - mb.mean);
  return sum / (a.size() - 1) / (ma.std * mb.std);
}

// On the LDS-01 normal arc (1.5 m/s, 2 rad/s: per 20 ms step dx 30 mm, dy 0.6 mm, dyaw 0.04 rad) with
// 10 % odometry noise, the measured increment of every step over the true one, recovered from the
// odometry's poses at the grid points: the factors 1 + 0.1 n. Over 500 steps the mean of a ratio is
// 1 within 4 standard errors (4 x 0.1 / sqrt(500) = 0.018), its standard deviation 0.1 within 4 of its
// standard errors (4 x 0.1 / sqrt(1000) = 0.013), and the components and consecutive steps are
// uncorrelated (|r| < 4 / sqrt(500) = 0.18).
TEST(SimOdometry, StepIncrementsAreScaledByIndependentFactors) {
  const ArcTrajectory truth({0.0, -0.75, 0.3}, 1.5, 2.0);
  const std::size_t steps = 500;
  const NoisyOdometry odometry(truth, -0.1, -0.1 + steps * 0.02, 0.1, 7);
  ASSERT_EQ(odometry.steps(), steps);
  std::vector<double> ratios[3];
  for (std::size_t j = 0; j < steps; ++j) {
    const double begin = -0.1 + j * 0.02, end = begin + 0.02;
    EXPECT_NEAR(odometry.stepStart(j), begin, 1e-12);
    const Eigen::Vector3d true_step = relative(truth.pose(begin), truth.pose(end));
    const Eigen::Vector3d measured = relative(odometry.pose(begin), odometry.pose(end));
    const NoisyOdometry::Factors factors = odometry.factors(begin + 0.01);
    const double expected[3] = {factors.x, factors.y, factors.yaw};
    for (int c = 0; c < 3; ++c) {
      ratios[c].push_back(measured[c] / true_step[c]);
      EXPECT_NEAR(ratios[c].back(), expected[c], 1e-9) << j << " " << c;
    }
  }
  for (int c = 0; c < 3; ++c) {
    const Moments m = moments(ratios[c]);
    std::printf("component %d: ratio mean %.4f std %.4f\n", c, m.mean, m.std);
    EXPECT_NEAR(m.mean, 1.0, 0.018) << c;
    EXPECT_NEAR(m.std, 0.1, 0.013) << c;
    EXPECT_LT(std::abs(correlation(ratios[c], ratios[(c + 1) % 3])), 0.18) << c;
    const std::vector<double> earlier(ratios[c].begin(), ratios[c].end() - 1);
    const std::vector<double> later(ratios[c].begin() + 1, ratios[c].end());
    EXPECT_LT(std::abs(correlation(earlier, later)), 0.18) << c;
  }
}

// The odometry's error after N steps is a sum of N independent errors: its variance grows like N (a
// random walk), not N^2 (a bias). Straight at 1.5 m/s the x error after N steps has standard deviation
// 0.1 x 30 mm x sqrt(N); on the 2 rad/s arc the heading error 0.1 x 0.04 rad x sqrt(N). Over 400 seeds
// the sample variance is within 4 x sqrt(2 / 400) = 28 % of that, at N = 25 and N = 100.
TEST(SimOdometry, DriftIsARandomWalk) {
  const ArcTrajectory line({1.0, 2.0, 0.5}, 1.5, 0.0);
  const ArcTrajectory arc({0.0, -0.75, 0.0}, 1.5, 2.0);
  const int runs = 400;
  for (const int n : {25, 100}) {
    std::vector<double> x_errors, lateral_errors, yaw_errors;
    for (int seed = 1; seed <= runs; ++seed) {
      const double end = n * 0.02;
      const NoisyOdometry on_line(line, 0.0, 2.0, 0.1, seed);
      const Eigen::Vector3d line_error = relative(line.pose(end), on_line.pose(end));
      x_errors.push_back(line_error.x());
      lateral_errors.push_back(std::abs(line_error.y()) + std::abs(line_error.z()));
      const NoisyOdometry on_arc(arc, 0.0, 2.0, 0.1, seed + 1000);
      yaw_errors.push_back(on_arc.pose(end).yaw - arc.pose(end).yaw);
    }
    const Moments x = moments(x_errors), yaw = moments(yaw_errors);
    const double x_sigma = 0.1 * 0.03 * std::sqrt(n), yaw_sigma = 0.1 * 0.04 * std::sqrt(n);
    std::printf("after %3d steps: x error %.2f mm (random walk %.2f), heading error %.2f mrad (%.2f)\n", n,
                1e3 * x.std, 1e3 * x_sigma, 1e3 * yaw.std, 1e3 * yaw_sigma);
    EXPECT_NEAR(x.std * x.std / (x_sigma * x_sigma), 1.0, 0.28) << n;
    EXPECT_NEAR(yaw.std * yaw.std / (yaw_sigma * yaw_sigma), 1.0, 0.28) << n;
    EXPECT_LT(std::abs(x.mean), 4.0 * x_sigma / std::sqrt(runs)) << n;
    EXPECT_LT(std::abs(yaw.mean), 4.0 * yaw_sigma / std::sqrt(runs)) << n;
    // On a straight line y and yaw have nothing to scale.
    EXPECT_LT(*std::max_element(lateral_errors.begin(), lateral_errors.end()), 1e-12) << n;
  }
}

// Between grid points (tf at 40 Hz samples mid-step): the pose at the step's start composed with the
// true motion since then, scaled by the step's factors; continuous at the grid points. Without noise
// the odometry is the truth, bit for bit.
TEST(SimOdometry, BetweenGridPointsAndWithoutNoise) {
  const ArcTrajectory truth({0.5, -0.75, 0.0}, 6.0, 5.0);
  const NoisyOdometry odometry(truth, -0.1, 1.0, 0.1, 3);
  EXPECT_EQ(odometry.steps(), 55u);
  for (const double t : {-0.075, 0.025, 0.4249, 0.99}) {
    const std::size_t j = static_cast<std::size_t>(std::floor((t + 0.1) / 0.02));
    const double start = -0.1 + j * 0.02;
    const NoisyOdometry::Factors f = odometry.factors(t);
    const Eigen::Vector3d since_start = relative(truth.pose(start), truth.pose(t));
    const Pose2 expected = composed(odometry.pose(start),
                                    {since_start.x() * f.x, since_start.y() * f.y, since_start.z() * f.yaw});
    const Pose2 actual = odometry.pose(t);
    EXPECT_NEAR(actual.x, expected.x, 1e-12) << t;
    EXPECT_NEAR(actual.y, expected.y, 1e-12) << t;
    EXPECT_NEAR(actual.yaw, expected.yaw, 1e-12) << t;
    const NoisyOdometry::Factors at_start = odometry.factors(start);
    EXPECT_EQ(at_start.x, f.x);
    EXPECT_EQ(at_start.yaw, f.yaw);
  }
  for (std::size_t j = 1; j < odometry.steps(); ++j) {
    const Pose2 before = odometry.pose(odometry.stepStart(j) - 1e-12),
                at = odometry.pose(odometry.stepStart(j));
    EXPECT_NEAR(before.x, at.x, 1e-9) << j;
    EXPECT_NEAR(before.yaw, at.yaw, 1e-9) << j;
  }
  EXPECT_THROW(odometry.pose(-0.11), std::out_of_range);
  EXPECT_THROW(odometry.pose(1.03), std::out_of_range);
  EXPECT_THROW(NoisyOdometry(truth, 0.0, 1.0, -0.1, 1), std::invalid_argument);

  const NoisyOdometry perfect(truth, -0.1, 1.0, 0.0, 3);
  for (double t = -0.1; t <= 1.0; t += 0.0123) {
    const Pose2 pose = perfect.pose(t), exact = truth.pose(t);
    EXPECT_EQ(pose.x, exact.x);
    EXPECT_EQ(pose.y, exact.y);
    EXPECT_EQ(pose.yaw, exact.yaw);
    EXPECT_EQ(perfect.factors(t).x, 1.0);
    EXPECT_EQ(perfect.factors(t).yaw, 1.0);
  }
}

// Odometry that reports a share of the true rotation (a wrong wheel base): every step's yaw increment
// is that share of the truth's, x and y as true; on a spin in place the heading turns 0.4x as far.
TEST(SimOdometry, YawScaleScalesEveryStepsRotation) {
  const ArcTrajectory arc({0.0, -0.75, 0.3}, 1.5, 2.0);
  const NoisyOdometry scaled(arc, 0.0, 2.0, 0.0, 1, 0.4);
  for (std::size_t j = 0; j < scaled.steps(); ++j) {
    const double begin = j * 0.02, end = begin + 0.02;
    const Eigen::Vector3d true_step = relative(arc.pose(begin), arc.pose(end));
    const Eigen::Vector3d measured = relative(scaled.pose(begin), scaled.pose(end));
    EXPECT_NEAR(measured.x(), true_step.x(), 1e-12) << j;
    EXPECT_NEAR(measured.y(), true_step.y(), 1e-12) << j;
    EXPECT_NEAR(measured.z(), 0.4 * true_step.z(), 1e-12) << j;
    EXPECT_EQ(scaled.factors(begin + 0.01).yaw, 0.4);
  }
  const ArcTrajectory spin({1.0, 2.0, 0.5}, 0.0, 1.5);
  const NoisyOdometry spin_scaled(spin, 0.0, 2.0, 0.0, 1, 0.4);
  EXPECT_NEAR(spin_scaled.pose(1.37).yaw - 0.5, 0.4 * 1.5 * 1.37, 1e-9);
  EXPECT_NEAR(spin_scaled.pose(1.37).x, 1.0, 1e-12);
  EXPECT_THROW(NoisyOdometry(arc, 0.0, 1.0, 0.0, 1, 0.0), std::invalid_argument);
  EXPECT_THROW(NoisyOdometry(arc, 0.0, 1.0, 0.0, 1, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace lidar_deskew::sim
