// The multi-line simulator's own truth: rays and distances against hand-worked geometry, sweeps of a
// standing and a moving sensor, the rough-ground pose in closed form, the scenarios and the truth file.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

#include "lidar_deskew/sim/cloud_scenario.h"
#include "support/temporary.h"

namespace lidar_deskew::sim {
namespace {

constexpr double kDegree = M_PI / 180.0;
constexpr double kMm = 1e-3;
const Pose3 kLevel = Pose3::fromXyzRpy(0.0, 0.0, 0.5, 0.0, 0.0, 0.0);  // sensor 0.5 m up, level

Eigen::Matrix3d rotX(double a) {
  Eigen::Matrix3d m;
  m << 1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a);
  return m;
}
Eigen::Matrix3d rotY(double a) {
  Eigen::Matrix3d m;
  m << std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a);
  return m;
}
Eigen::Matrix3d rotZ(double a) {
  Eigen::Matrix3d m;
  m << std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1;
  return m;
}

std::shared_ptr<const Trajectory3> standing(const Pose2& where) {
  return std::make_shared<PlanarTrajectory3>(
      std::make_shared<PiecewiseTrajectory>(where, std::vector<MotionPiece>{{1.0, 0.0, 0.0, 0.0}}));
}

std::vector<Eigen::Vector3d> positions(const SimulatedCloud& cloud) {
  std::vector<Eigen::Vector3d> result;
  for (const SimulatedPoint& point : cloud.points) {
    if (point.is_return)
      result.push_back(point.position);
  }
  return result;
}

TEST(Sim3d, PoseFollowsRep103AndComposes) {
  const Pose3 pose = Pose3::fromXyzRpy(1.0, -2.0, 0.5, 0.1, -0.2, 0.7);
  const Eigen::Matrix3d expected = rotZ(0.7) * rotY(-0.2) * rotX(0.1);
  EXPECT_LT((pose.rotation - expected).norm(), 1e-15);
  // Yaw 90 deg: the child's x axis is the parent's y axis.
  EXPECT_LT((Pose3::fromXyzRpy(0, 0, 0, 0, 0, M_PI / 2).apply({1, 0, 0}) - Eigen::Vector3d(0, 1, 0)).norm(),
            1e-15);
  // Pitch +90 deg (about y) turns x down: nose down is positive pitch.
  EXPECT_LT((Pose3::fromXyzRpy(0, 0, 0, 0, M_PI / 2, 0).apply({1, 0, 0}) - Eigen::Vector3d(0, 0, -1)).norm(),
            1e-15);
  const Pose3 local = Pose3::fromXyzRpy(0.3, 0.1, -0.2, -0.05, 0.02, 1.2);
  const Eigen::Vector3d point(2.0, -1.0, 0.4);
  EXPECT_LT((pose.compose(local).apply(point) - pose.apply(local.apply(point))).norm(), 1e-14);
  EXPECT_LT((pose.applyInverse(pose.apply(point)) - point).norm(), 1e-14);
  const Pose3 identity = pose.compose(pose.inverse());
  EXPECT_LT(identity.position.norm(), 1e-15);
  EXPECT_LT((identity.rotation - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  // The planar pose at a height.
  const Pose3 planar = Pose3::fromPose2({1.0, 2.0, 0.3}, 0.5);
  EXPECT_LT((planar.apply({1, 0, 0}) - Eigen::Vector3d(1 + std::cos(0.3), 2 + std::sin(0.3), 0.5)).norm(),
            1e-15);
}

TEST(Sim3d, RaysHitTheHallAtHandWorkedRanges) {
  const World3 hall = World3::hall();
  const auto cast = [&](Eigen::Vector3d origin, Eigen::Vector3d direction) {
    const std::optional<double> range = hall.castRay(origin, direction.normalized());
    EXPECT_TRUE(range.has_value());
    return range.value_or(-1.0);
  };
  // Straight down and straight up from a sensor 0.5 m high.
  EXPECT_NEAR(cast({-10.0, 0.5, 0.5}, {0, 0, -1}), 0.5, 1e-12);
  EXPECT_NEAR(cast({-10.0, 0.5, 0.5}, {0, 0, 1}), 2.5, 1e-12);
  // Along the hall to the east wall (x = 20), passing beside every pillar; south to y = -5.
  EXPECT_NEAR(cast({-10.0, 0.5, 1.0}, {1, 0, 0}), 30.0, 1e-12);
  EXPECT_NEAR(cast({0.0, 0.0, 1.5}, {0, -1, 0}), 5.0, 1e-12);
  // 10 deg up to the south wall: 5 / cos 10 deg, at z = 1 + 5 tan 10 deg.
  const double elevation = 10.0 * kDegree;
  EXPECT_NEAR(cast({0.0, 0.0, 1.0}, {0, -std::cos(elevation), std::sin(elevation)}),
              5.0 / std::cos(elevation), 1e-12);
  // 45 deg down to the floor at (2, 0, 0).
  EXPECT_NEAR(cast({0.0, 0.0, 2.0}, {1, 0, -1}), 2.0 * std::sqrt(2.0), 1e-12);
  // South onto the round pillar at (-6, -1.5), r 0.3: its face at y = -1.2.
  EXPECT_NEAR(cast({-6.0, 1.0, 1.0}, {0, -1, 0}), 2.2, 1e-12);
  // East along the round pillar's centre line: its west face at x = -6.3.
  EXPECT_NEAR(cast({-8.0, -1.5, 1.0}, {1, 0, 0}), 1.7, 1e-12);
  // West onto the square pillar at x -4 .. -3.5, y -2.8 .. -2.3: its east face.
  EXPECT_NEAR(cast({0.0, -2.5, 1.0}, {-1, 0, 0}), 3.5, 1e-12);
  // A world of one short wall: a ray over it misses.
  World3 wall;
  wall.addWall({1.0, -1.0}, {1.0, 1.0}, 0.0, 1.0);
  EXPECT_NEAR(wall.castRay({0, 0, 0.5}, {1, 0, 0}).value_or(-1.0), 1.0, 1e-15);
  EXPECT_FALSE(wall.castRay({0, 0, 1.5}, {1, 0, 0}).has_value());
  EXPECT_FALSE(wall.castRay({0, 0, 0.5}, {-1, 0, 0}).has_value());
}

TEST(Sim3d, DistancesToTheHallAreHandWorked) {
  const World3 hall = World3::hall();
  // Points on each kind of surface.
  EXPECT_NEAR(hall.distanceTo({-20.0, 0.0, 1.0}), 0.0, 1e-12);   // west wall
  EXPECT_NEAR(hall.distanceTo({0.0, -3.0, 0.0}), 0.0, 1e-12);    // floor
  EXPECT_NEAR(hall.distanceTo({0.0, -3.0, 3.0}), 0.0, 1e-12);    // ceiling
  EXPECT_NEAR(hall.distanceTo({-5.7, -1.5, 1.2}), 0.0, 1e-12);   // round pillar
  EXPECT_NEAR(hall.distanceTo({-3.75, -2.3, 2.0}), 0.0, 1e-12);  // square pillar
  EXPECT_NEAR(hall.distanceTo({5.0, 10.0, 0.0}), 0.0, 1e-12);    // corridor floor
  // Free space: nearest is the floor (or ceiling) 1.5 m away, the south wall 2 m.
  EXPECT_NEAR(hall.distanceTo({0.0, -3.0, 1.5}), 1.5, 1e-12);
  EXPECT_NEAR(hall.distanceTo({0.0, -4.5, 1.5}), 0.5, 1e-12);
  // Beside the round pillar: 0.2 m from its side.
  EXPECT_NEAR(hall.distanceTo({-6.0, -1.0, 1.5}), 0.2, 1e-12);
  // Outside the room, below the floor: 10 m west of the west wall and 1 m down: sqrt(101).
  EXPECT_NEAR(hall.distanceTo({-30.0, 0.0, -1.0}), std::sqrt(101.0), 1e-12);
  // A floor of one square: beyond its edge the distance runs to the edge.
  World3 square;
  square.addHorizontal({{0, 0}, {1, 0}, {1, 1}, {0, 1}}, 0.0);
  EXPECT_NEAR(square.distanceTo({2.0, 0.5, 1.0}), std::sqrt(2.0), 1e-15);
  EXPECT_NEAR(square.distanceTo({0.5, 0.5, -0.25}), 0.25, 1e-15);
  EXPECT_FALSE(square.castRay({2.0, 0.5, 1.0}, {0, 0, -1}).has_value());
}

TEST(Sim3d, StandingVlp16SweepLiesOnTheSurfaces) {
  const World3 hall = World3::hall();
  const SpinningLidarModel vlp16 = SpinningLidarModel::vlp16();
  const Pose3 mount = Pose3::fromXyzRpy(0.1, 0.0, 0.5, 1.0 * kDegree, 2.0 * kDegree, 0.0);
  const auto trajectory = standing({-10.0, 0.5, 0.3});
  const SimulatedCloud cloud = simulateSweep(hall, *trajectory, mount, vlp16, 0.0);
  // A closed room: every ray returns, 16 x 1800 points in firing order.
  ASSERT_EQ(cloud.points.size(), 16u * 1800u);
  EXPECT_FALSE(cloud.organized);
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    EXPECT_EQ(cloud.points[i].column, static_cast<int>(i / 16));
    EXPECT_EQ(cloud.points[i].ring, static_cast<int>(i % 16));
    EXPECT_TRUE(cloud.points[i].is_return);
  }
  const Pose3 sensor = trajectory->pose(0.0).compose(mount);
  const std::vector<double> distances = distancesToWorld(hall, sensor, positions(cloud));
  EXPECT_LT(errorStats(distances).max, 1e-9);
  for (const SimulatedPoint& point : cloud.points) {
    EXPECT_LT((sensor.apply(point.position) - point.world_hit).norm(), 1e-9);
    EXPECT_NEAR(point.range, point.position.norm(), 1e-12);
  }
  // Ring 0 looks 15 deg down, ring 15 15 deg up (in the sensor frame); column 0 looks backwards, and
  // the VLP-16 turns clockwise: column 450 (a quarter turn later) looks left (+y).
  EXPECT_NEAR(vlp16.direction(0, 0).z(), std::sin(-15.0 * kDegree), 1e-15);
  EXPECT_NEAR(vlp16.direction(15, 0).z(), std::sin(15.0 * kDegree), 1e-15);
  EXPECT_NEAR(vlp16.direction(7, 0).x(), -std::cos(-1.0 * kDegree), 1e-15);
  EXPECT_NEAR(vlp16.direction(7, 450).y(), std::cos(-1.0 * kDegree), 1e-12);
}

TEST(Sim3d, StandingOs1SweepIsAnOrganizedImage) {
  const World3 hall = World3::hall();
  const SpinningLidarModel os1 = SpinningLidarModel::os1_64();
  const Pose3 mount = Pose3::fromXyzRpy(0.1, 0.0, 0.5, 1.0 * kDegree, 2.0 * kDegree, 0.0);
  const auto trajectory = standing({-10.0, 0.5, 0.0});
  const SimulatedCloud cloud = simulateSweep(hall, *trajectory, mount, os1, 0.3);
  ASSERT_EQ(cloud.points.size(), 64u * 1024u);
  EXPECT_TRUE(cloud.organized);
  for (int ring = 0; ring < 64; ++ring) {
    for (int column = 0; column < 1024; ++column) {
      const SimulatedPoint& point = cloud.points[static_cast<std::size_t>(ring) * 1024 + column];
      EXPECT_EQ(point.ring, ring);
      EXPECT_EQ(point.column, column);
    }
  }
  EXPECT_NEAR(os1.ring_elevations.front(), 16.6 * kDegree, 1e-15);
  EXPECT_NEAR(os1.ring_elevations.back(), -16.6 * kDegree, 1e-15);
  // Counter-clockwise: a quarter turn after looking backwards it looks right (-y).
  EXPECT_NEAR(os1.direction(31, 256).y(), -std::cos(os1.ring_elevations[31]), 1e-12);
  const Pose3 sensor = trajectory->pose(0.3).compose(mount);
  EXPECT_LT(errorStats(distancesToWorld(hall, sensor, positions(cloud))).max, 1e-9);

  // On an endless floor alone the upward half of the rings has no return: zeros, NaN truth, kept.
  World3 floor;
  floor.addHorizontal({{-1e4, -1e4}, {1e4, -1e4}, {1e4, 1e4}, {-1e4, 1e4}}, 0.0);
  const Pose3 level = Pose3::fromXyzRpy(0.0, 0.0, 0.5, 0.0, 0.0, 0.0);
  const SimulatedCloud open = simulateSweep(floor, *trajectory, level, os1, 0.0);
  ASSERT_EQ(open.points.size(), 64u * 1024u);
  std::size_t returns = 0;
  for (const SimulatedPoint& point : open.points) {
    const bool down = os1.ring_elevations[point.ring] < 0.0;  // 0.5 / sin(0.26 deg) = 109 m < 120 m
    EXPECT_EQ(point.is_return, down) << point.ring;
    if (!point.is_return) {
      EXPECT_EQ(point.position, Eigen::Vector3d::Zero());
      EXPECT_TRUE(point.world_hit.array().isNaN().all());
    } else {
      EXPECT_NEAR(point.world_hit.z(), 0.0, 1e-12);
    }
    returns += point.is_return;
  }
  EXPECT_EQ(returns, 32u * 1024u);
  // The VLP-16, dense, keeps only its 8 downward rings (the flattest one reaches 28.6 m < 100 m).
  const SimulatedCloud dense = simulateSweep(floor, *trajectory, level, SpinningLidarModel::vlp16(), 0.0);
  EXPECT_EQ(dense.points.size(), 8u * 1800u);
}

TEST(Sim3d, ColumnTimesAreEvenlySpacedOverOneRevolution) {
  const World3 hall = World3::hall();
  for (const SpinningLidarModel& model : {SpinningLidarModel::vlp16(), SpinningLidarModel::os1_64()}) {
    const double start = 0.7;
    const SimulatedCloud cloud = simulateSweep(hall, *standing({-10.0, 0.5, 0.0}), kLevel, model, start);
    const double column_period = 1.0 / (model.rate * model.columns);
    EXPECT_EQ(cloud.start_time, start);
    // The last column fires one column period before the next sweep's first.
    EXPECT_NEAR(cloud.end_time + column_period, start + 1.0 / model.rate, 1e-15);
    for (const SimulatedPoint& point : cloud.points)
      EXPECT_NEAR(point.time, start + point.column * column_period, 1e-15);
    if (!model.organized) {  // firing order: times never go back
      for (std::size_t i = 1; i < cloud.points.size(); ++i)
        ASSERT_GE(cloud.points[i].time, cloud.points[i - 1].time);
    }
  }
}

TEST(Sim3d, RoughGroundPoseIsTheClosedForm) {
  const Pose2 start{-10.0, 0.5, 0.2};
  auto planar = std::make_shared<PiecewiseTrajectory>(start, std::vector<MotionPiece>{{1.0, 1.5, 0.0, 2.0}});
  const RoughGround ground;  // z 2 cm at 3 Hz, pitch 2 deg at 2.3 Hz, roll 1.5 deg at 1.7 Hz
  const RoughGroundTrajectory3 rough(planar, ground);
  EXPECT_NEAR(ground.z_amplitude, 0.02, 0);
  for (const double t : {0.0, 0.0371, 0.37, 1.25}) {
    const Pose2 flat = integrateUnicycle(start, 1.5, 0.0, 2.0, t);
    const double z = 0.02 * std::sin(2 * M_PI * 3.0 * t);
    const double pitch = 2.0 * kDegree * std::sin(2 * M_PI * 2.3 * t);
    const double roll = 1.5 * kDegree * std::sin(2 * M_PI * 1.7 * t);
    const Pose3 pose = rough.pose(t);
    EXPECT_NEAR(pose.position.x(), flat.x, 1e-12);
    EXPECT_NEAR(pose.position.y(), flat.y, 1e-12);
    EXPECT_NEAR(pose.position.z(), z, 1e-15);
    EXPECT_LT((pose.rotation - rotZ(flat.yaw) * rotY(pitch) * rotX(roll)).norm(), 1e-14) << t;
  }
  // Fully 3D at t = 0.37 s: height, roll and pitch all well away from zero.
  const Pose3 pose = rough.pose(0.37);
  EXPECT_GT(std::abs(pose.position.z()), 0.01);
  EXPECT_GT(std::abs(pose.rotation(2, 0)), 0.5 * kDegree);  // -sin(pitch)
  EXPECT_GT(std::abs(pose.rotation(2, 1)), 0.5 * kDegree);  // cos(pitch) sin(roll)
  // Flat ground: the planar pose at z = 0.
  const PlanarTrajectory3 flat(planar);
  EXPECT_LT(
      (flat.pose(0.37).position - Eigen::Vector3d(planar->pose(0.37).x, planar->pose(0.37).y, 0)).norm(),
      1e-15);
}

TEST(Sim3d, MovingSensorRawCloudIsOffBySpeedTimesTime) {
  // 1.5 m/s straight ahead, sensor level: a point fired dt after the sweep start, placed with the
  // start pose, lies exactly 1.5 dt behind its true hit, along the motion.
  const double speed = 1.5;
  const Pose2 start{-10.0, 0.5, 0.0};
  const PlanarTrajectory3 trajectory(
      std::make_shared<PiecewiseTrajectory>(start, std::vector<MotionPiece>{{1.0, speed, 0.0, 0.0}}));
  const World3 hall = World3::hall();
  const Pose3 mount = Pose3::fromXyzRpy(0.0, 0.0, 0.5, 0.0, 0.0, 0.0);
  const SimulatedCloud cloud =
      simulateSweep(hall, trajectory, mount, SpinningLidarModel::vlp16(), 0.2, /*noise=*/nullptr);
  const Pose3 at_start = trajectory.pose(0.2).compose(mount);
  std::vector<double> offsets;
  for (const SimulatedPoint& point : cloud.points) {
    const double dt = point.time - 0.2;
    const Eigen::Vector3d placed = at_start.apply(point.position);
    EXPECT_LT((placed - (point.world_hit - Eigen::Vector3d(speed * dt, 0, 0))).norm(), 1e-9);
    offsets.push_back(hall.distanceTo(placed));
    EXPECT_LE(offsets.back(), speed * dt + 1e-9);
  }
  const ErrorStats raw = errorStats(offsets).scaled(1e3);
  std::printf("raw VLP-16 at 1.5 m/s placed with the sweep-start pose: %.1f mm RMS, %.1f mm max\n", raw.rms,
              raw.max);
  EXPECT_GT(raw.max, 0.8 * speed * 0.1 / kMm);  // about v T = 150 mm at the end of the sweep
  EXPECT_LT(raw.max, speed * 0.1 / kMm);
  EXPECT_GT(raw.rms, 10.0);
}

TEST(Sim3d, NoiseMovesPointsAlongTheirBeam) {
  const World3 hall = World3::hall();
  std::mt19937 rng(7);
  const SpinningLidarModel vlp16 = SpinningLidarModel::vlp16();
  const SimulatedCloud noisy = simulateSweep(hall, *standing({-10.0, 0.5, 0.0}), kLevel, vlp16, 0.0, &rng);
  const Eigen::Vector3d sensor(-10.0, 0.5, 0.5);  // standing, level
  std::vector<double> along;
  for (const SimulatedPoint& point : noisy.points) {
    const Eigen::Vector3d beam = vlp16.direction(point.ring, point.column);
    EXPECT_LT((point.position - point.range * beam).norm(), 1e-12);
    EXPECT_LT((sensor + (point.world_hit - sensor).norm() * beam - point.world_hit).norm(), 1e-9);
    along.push_back(point.range - (point.world_hit - sensor).norm());
  }
  EXPECT_NEAR(errorStats(along).rms, vlp16.range_sigma, 0.1 * vlp16.range_sigma);
}

/// Over the bag's tf span (0.1 s before the first sweep to 0.1 s after the last one's end, 10 Hz) the
/// sensor stays under the hall's ceiling and at least 0.4 m from every surface.
void expectInsideTheHall(const CloudScenario& scenario) {
  const World3 hall = World3::hall();
  const auto trajectory = scenario.trajectory();
  double nearest = 1e9;
  for (double t = -0.1; t <= scenario.duration + 0.2 + 1e-9; t += 0.002) {
    const Pose3 sensor = trajectory->pose(t).compose(scenario.mount);
    nearest = std::min(nearest, hall.distanceTo(sensor.position));
    ASSERT_NEAR(hall.castRay(sensor.position, Eigen::Vector3d::UnitZ()).value_or(0.0),
                World3::kHallHeight - sensor.position.z(), 1e-9)
        << scenario.name << " left the hall at t = " << t;
  }
  EXPECT_GT(nearest, 0.4) << scenario.name;
}

TEST(Sim3d, CloudScenariosStayInsideTheHall) {
  const std::vector<CloudScenario> scenarios = cloudScenarios();
  EXPECT_EQ(scenarios.size(), 14u);
  std::set<std::string> names;
  for (const CloudScenario& scenario : scenarios) {
    names.insert(scenario.name);
    EXPECT_EQ(findCloudScenario(scenario.name).name, scenario.name);
    EXPECT_EQ(scenario.sweepStartTimes().size(), 10u) << scenario.name;
    EXPECT_NE(scenario.motion, "smooth") << scenario.name;
    expectInsideTheHall(scenario);
  }
  EXPECT_EQ(names.size(), scenarios.size());
  EXPECT_TRUE(names.count("VLP16/rough/arc") && names.count("OS1-64/high/turn"));
  EXPECT_THROW(findCloudScenario("VLP16/nope"), std::invalid_argument);
  EXPECT_TRUE(findCloudScenario("OS1-64/rough/arc").rough.has_value());
  EXPECT_FALSE(findCloudScenario("OS1-64/normal/arc").rough.has_value());
}

/// The smooth drives, VLP16 and OS1-64 each at normal, high and rough: named as the suite, not in
/// cloudScenarios() (its tables stay as they are) but found by name, 13 sweeps, inside the hall.
TEST(Sim3d, CloudSmoothScenariosAreAllThere) {
  const std::vector<CloudScenario> scenarios = cloudSmoothScenarios();
  std::vector<std::string> names;
  for (const CloudScenario& scenario : scenarios) {
    names.push_back(scenario.name);
    EXPECT_EQ(findCloudScenario(scenario.name).name, scenario.name);
    EXPECT_EQ(scenario.motion, "smooth");
    EXPECT_EQ(scenario.sweepStartTimes().size(), 13u) << scenario.name;
    EXPECT_EQ(scenario.rough.has_value(), scenario.speed == "rough") << scenario.name;
    expectInsideTheHall(scenario);
  }
  EXPECT_EQ(names,
            (std::vector<std::string>{"VLP16/normal/smooth", "VLP16/high/smooth", "VLP16/rough/smooth",
                                      "OS1-64/normal/smooth", "OS1-64/high/smooth", "OS1-64/rough/smooth"}));
  // High speed: the sensor off the rotation centre, as the other high-speed scenarios.
  EXPECT_EQ(findCloudScenario("OS1-64/high/smooth").mount.position,
            findCloudScenario("OS1-64/high/arc").mount.position);
  EXPECT_EQ(findCloudScenario("VLP16/rough/smooth").mount.position,
            findCloudScenario("VLP16/rough/arc").mount.position);
}

/// Every smooth drive is what it claims: the base's x, y and heading follow the unicycle with speed
/// V cos(2 pi t / 2 s) and turn rate W cos(2 pi t / 1.3 s) from (-10, -1.5, 0) (V, W = 1.5 m/s, 2 rad/s;
/// 6 m/s, 5 rad/s at high), integrated here independently by the classical Runge-Kutta method in 10 us
/// steps; z, roll and pitch are 0 on flat ground and RoughGround's sines on rough ground; the sensor is
/// that pose composed with the mount, written out by hand (Rz Ry Rx). Checked every 10 ms over the bag's
/// tf span after t = 0, to 1.4 s.
TEST(Sim3d, CloudSmoothScenariosFollowTheCosines) {
  for (const CloudScenario& scenario : cloudSmoothScenarios()) {
    const bool high = scenario.speed == "high";
    const double speed = high ? 6.0 : 1.5, yaw_rate = high ? 5.0 : 2.0;
    const auto derivative = [&](double t, const Eigen::Vector3d& state) {
      const double v = speed * std::cos(M_PI * t);
      return Eigen::Vector3d(v * std::cos(state.z()), v * std::sin(state.z()),
                             yaw_rate * std::cos(2.0 * M_PI * t / 1.3));
    };
    const bool rough = scenario.speed == "rough";
    const auto trajectory = scenario.trajectory();
    Eigen::Vector3d state(-10.0, -1.5, 0.0);
    const double h = 1e-5;
    double worst_position = 0.0, worst_rotation = 0.0, worst_sensor = 0.0;
    for (int i = 0; i <= 140000; ++i) {
      const double t = i * h;
      if (i % 1000 == 0) {
        const double z = rough ? 0.02 * std::sin(2 * M_PI * 3.0 * t) : 0.0;
        const double pitch = rough ? 2.0 * kDegree * std::sin(2 * M_PI * 2.3 * t) : 0.0;
        const double roll = rough ? 1.5 * kDegree * std::sin(2 * M_PI * 1.7 * t) : 0.0;
        const Eigen::Matrix3d rotation = rotZ(state.z()) * rotY(pitch) * rotX(roll);
        const Eigen::Vector3d position(state.x(), state.y(), z);
        const Pose3 base = trajectory->pose(t);
        worst_position = std::max(worst_position, (base.position - position).norm());
        worst_rotation = std::max(worst_rotation, (base.rotation - rotation).norm());
        const Eigen::Vector3d sensor = position + rotation * scenario.mount.position;
        worst_sensor = std::max(worst_sensor, (base.compose(scenario.mount).position - sensor).norm());
      }
      const Eigen::Vector3d k1 = derivative(t, state), k2 = derivative(t + h / 2, state + h / 2 * k1);
      const Eigen::Vector3d k3 = derivative(t + h / 2, state + h / 2 * k2),
                            k4 = derivative(t + h, state + h * k3);
      state += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    std::printf("%s vs Runge-Kutta: base %.2e m, rotation %.2e, sensor %.2e m\n", scenario.name.c_str(),
                worst_position, worst_rotation, worst_sensor);
    EXPECT_LT(worst_position, 2e-6) << scenario.name;
    EXPECT_LT(worst_rotation, 1e-9) << scenario.name;
    EXPECT_LT(worst_sensor, 2e-6) << scenario.name;
  }
  // The twist changes between tf samples, and not linearly: over three samples 20 ms apart (50 Hz) the
  // speed's and the turn rate's second differences are about -V (pi h)^2 = -0.024 m/s and
  // -W (2 pi h / 1.3)^2 = -0.047 rad/s near t = 0 (h = 20 ms).
  const CloudScenario high = findCloudScenario("VLP16/high/smooth");
  const PiecewiseTrajectory planar(high.start, high.pieces);
  EXPECT_LT(planar.speed(0.02) - 2 * planar.speed(0.04) + planar.speed(0.06), -0.02);
  EXPECT_LT(planar.yawRate(0.02) - 2 * planar.yawRate(0.04) + planar.yawRate(0.06), -0.04);
}

TEST(Sim3d, CloudTruthFileRoundTripsExactly) {
  const CloudScenario scenario = findCloudScenario("VLP16/rough/arc");
  CloudTruth truth;
  truth.scenario = scenario.name;
  truth.sensor = scenario.lidar.name;
  truth.convention = "velodyne_first";
  truth.epoch = 1'700'000'000'123'456'789;
  truth.range_sigma = 0.03;
  truth.mount = scenario.mount;
  truth.start = scenario.start;
  truth.pieces = findCloudScenario("VLP16/varying/varying").pieces;
  truth.rough = RoughGround{0.01, 3.3, 0.02, 2.1, 0.03, 1.1};
  truth.sweep_start_times = scenario.sweepStartTimes();
  const std::string path = test::temporary("sim3d", "truth.txt");
  writeCloudTruth(truth, path);
  const CloudTruth read = readCloudTruth(path);
  EXPECT_EQ(read.scenario, truth.scenario);
  EXPECT_EQ(read.world, "hall");
  EXPECT_EQ(read.sensor, "VLP16");
  EXPECT_EQ(read.convention, "velodyne_first");
  EXPECT_EQ(read.epoch, truth.epoch);
  EXPECT_EQ(read.range_sigma, truth.range_sigma);
  EXPECT_EQ(read.mount.position, truth.mount.position);
  EXPECT_EQ(read.mount.rotation, truth.mount.rotation);
  EXPECT_EQ(read.sweep_start_times, truth.sweep_start_times);
  ASSERT_TRUE(read.rough.has_value());
  EXPECT_EQ(read.rough->roll_frequency, 1.1);
  ASSERT_EQ(read.pieces.size(), truth.pieces.size());
  for (const double t : {-0.05, 0.0, 0.333, 1.1}) {
    const Pose3 a = truth.sensorPoseAt(t), b = read.sensorPoseAt(t);
    EXPECT_EQ(a.position, b.position);
    EXPECT_EQ(a.rotation, b.rotation);
  }
  EXPECT_EQ(read.sensorPose(truth.epoch + 250'000'000).position, truth.sensorPoseAt(0.25).position);
  EXPECT_EQ(SpinningLidarModel::byName(read.sensor).columns, 1800);
  EXPECT_EQ(World3::byName(read.world).walls().size(), World3::hall().walls().size());

  std::ofstream(path, std::ios::app) << "mount 1 2\n";
  try {
    readCloudTruth(path);
    FAIL() << "a malformed line was accepted";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(
        std::string(error.what()).find(":" + std::to_string(9 + truth.pieces.size() + 1 + 10 + 1) + ":"),
        std::string::npos)
        << error.what();
  }
  std::remove(path.c_str());
}

TEST(Sim3d, SweepSimulationIsFast) {
  const World3 hall = World3::hall();
  const CloudScenario scenario = findCloudScenario("VLP16/rough/arc");
  const auto trajectory = scenario.trajectory();
  for (const SpinningLidarModel& model : {SpinningLidarModel::vlp16(), SpinningLidarModel::os1_64()}) {
    const auto begin = std::chrono::steady_clock::now();
    const SimulatedCloud cloud = simulateSweep(hall, *trajectory, scenario.mount, model, 0.0);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
    std::printf("%s sweep in the hall: %zu points in %.1f ms\n", model.name.c_str(), cloud.points.size(),
                seconds * 1e3);
    EXPECT_LT(seconds, 1.0);
  }
}

}  // namespace
}  // namespace lidar_deskew::sim
