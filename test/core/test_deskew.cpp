// The correction (paper eq. 1-7) against closed-form truth from the simulator. Tolerances in mm.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "support/truth.h"

namespace lidar_deskew {
namespace {

using core::DeskewConfig;
using core::DeskewedScan;
using core::Reference;
using core::ScanDeskewer;
using core::TimeNs;
using sim::ArcTrajectory;
using sim::LidarModel;
using sim::Pose2;

using test::kEpoch;
using test::kMm;

/// Raw and corrected error [m] of one simulated scan, corrected with `config` from `motion`.
struct CaseResult {
  test::ErrorStats raw;
  test::ErrorStats corrected;
  DeskewedScan scan;
};

CaseResult runCase(const sim::SimulatedScan& simulated, const sim::Trajectory& trajectory, const Pose2& mount,
                   const core::MotionSource& motion, const DeskewConfig& config,
                   const core::TimingConfig& timing_config = core::TimingConfig()) {
  CaseResult result;
  ScanDeskewer deskewer(config);
  const core::BeamTiming timing = core::resolveTiming(simulated.scan, timing_config);
  deskewer.deskew(simulated.scan, timing, test::toMrpt(mount), motion, result.scan);
  const auto truth = test::truePointsAtReference(simulated, result.scan, trajectory, mount, kEpoch);
  result.corrected = test::errorStats(test::pointErrors(result.scan, truth));
  const auto raw = test::rawPoints(simulated.scan, result.scan);
  std::vector<double> raw_errors;
  for (std::size_t j = 0; j < raw.size(); ++j)
    raw_errors.push_back((raw[j] - truth[j]).norm());
  result.raw = test::errorStats(raw_errors);
  return result;
}

// tf2's own interpolation: these tests hold the knots to per-sample lookups of the samples given.
DeskewConfig withReference(Reference reference, double knot_interval = 0.005,
                           core::Interpolation interpolation = core::Interpolation::kLinear) {
  DeskewConfig config;
  config.reference = reference;
  config.knot_interval = knot_interval;
  config.interpolation = interpolation;
  return config;
}

TEST(Deskew, StaticRobotGivesThePlainPolarProjection) {
  const sim::World world = sim::World::demoRoom();
  const ArcTrajectory still({1.0, -0.5, 0.7}, 0.0, 0.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const auto simulated = sim::simulateScan(world, still, mount, LidarModel::ild26tri(), kEpoch, 2.0);
  const auto samples = test::sampleTrajectory(still, kEpoch, 1.9, 2.3, 0.02);
  for (const double knot_interval : {0.005, 0.0}) {
    ScanDeskewer deskewer(withReference(Reference::kStart, knot_interval));
    DeskewedScan out;
    deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), test::toMrpt(mount), samples,
                    out);
    ASSERT_EQ(out.points.size(), 360u);
    const auto raw = test::rawPoints(simulated.scan, out);
    for (std::size_t j = 0; j < out.points.size(); ++j) {
      EXPECT_NEAR(out.points[j].position.x(), raw[j].x(), 1e-9);
      EXPECT_NEAR(out.points[j].position.y(), raw[j].y(), 1e-9);
      EXPECT_NEAR(out.points[j].position.z(), 0.0, 1e-9);
      const core::PolarPoint polar = core::toPolar(out.points[j].position);
      EXPECT_NEAR(polar.range, simulated.scan.ranges[out.points[j].beam_index], 1e-9);
    }
  }
}

// Paper case 1: the robot yaws at minus the scan's angular rate, so every beam looks the same way in
// the world and sees one point. Raw: a circle of points; corrected: all on that one true point.
TEST(Deskew, PaperCase1CounterRotationCollapsesToOnePoint) {
  sim::World world;
  world.add({3.0, -20.0}, {3.0, 20.0});  // a wall 3 m ahead
  const LidarModel model = LidarModel::ild26tri();
  const double scan_rate = 2.0 * M_PI * model.rate;  // [rad/s] of the beam
  // Beam 0 looks along -pi in the laser frame: face the robot backwards so it looks along +x.
  const ArcTrajectory facing({0.0, 0.0, M_PI}, 0.0, -scan_rate);
  const Pose2 mount{0.0, 0.0, 0.0};
  const auto simulated = sim::simulateScan(world, facing, mount, model, kEpoch, 0.0);
  const auto samples = test::sampleTrajectory(facing, kEpoch, 0.0, 0.13, 0.001);
  const CaseResult result = runCase(simulated, facing, mount, samples, withReference(Reference::kStart));
  ASSERT_EQ(result.scan.points.size(), 360u);
  // Every beam measured 3 m; raw points spread around the whole circle.
  for (float range : simulated.scan.ranges)
    EXPECT_NEAR(range, 3.0, 1e-5);
  double raw_spread = 0.0;
  const auto raw = test::rawPoints(simulated.scan, result.scan);
  for (const auto& p : raw)
    raw_spread = std::max(raw_spread, (p - raw.front()).norm());
  EXPECT_GT(raw_spread, 5.9);
  // Corrected: all on the one true point, world (3, 0), which is (-3, 0) in the laser frame at t_ref.
  const Eigen::Vector2d true_point(-3.0, 0.0);
  for (const auto& point : result.scan.points) {
    EXPECT_LT((point.position.head<2>() - true_point).norm(), 0.01 * kMm);
  }
  EXPECT_LT(result.corrected.max, 0.01 * kMm);
}

// Paper case 2: driving at v toward a wall perpendicular to the motion. Beam i at time t_i sees the
// wall from x = v t_i, so its raw point has x = D - v t_i: the raw wall tilts by v * sweep time.
TEST(Deskew, PaperCase2WallAheadIsTiltedRawAndStraightCorrected) {
  const double distance = 4.0, speed = 1.5;
  sim::World world;
  world.add({distance, -40.0}, {distance, 40.0});
  const LidarModel model = LidarModel::ild26tri();
  const ArcTrajectory drive({0.0, 0.0, 0.0}, speed, 0.0);
  const Pose2 mount{0.0, 0.0, 0.0};
  const auto simulated = sim::simulateScan(world, drive, mount, model, kEpoch, 0.0);
  const auto samples = test::sampleTrajectory(drive, kEpoch, 0.0, 0.13, 0.02);
  const CaseResult result = runCase(simulated, drive, mount, samples, withReference(Reference::kStart));
  ASSERT_GT(result.scan.points.size(), 150u);

  const auto raw = test::rawPoints(simulated.scan, result.scan);
  double raw_min_x = INFINITY, raw_max_x = -INFINITY;
  for (std::size_t j = 0; j < raw.size(); ++j) {
    const double t = simulated.beam_times[result.scan.points[j].beam_index];
    EXPECT_NEAR(raw[j].x(), distance - speed * t, 0.01 * kMm);  // the predicted tilt
    raw_min_x = std::min(raw_min_x, raw[j].x());
    raw_max_x = std::max(raw_max_x, raw[j].x());
    EXPECT_NEAR(result.scan.points[j].position.x(), distance, 0.01 * kMm);  // straight, at D at t_ref
  }
  // The wall is seen from beam ~98 (-82 deg) to ~262 (+82 deg): 164 beams of 0.125/360 s at 1.5 m/s.
  EXPECT_NEAR(raw_max_x - raw_min_x,
              speed * (result.scan.points.back().time_offset - result.scan.points.front().time_offset),
              0.01 * kMm);
  EXPECT_GT(raw_max_x - raw_min_x, 0.08);
}

struct ArcCase {
  LidarModel model;
  double speed;     // [m/s]
  double yaw_rate;  // [rad/s]
};

class ArcWithMountOffset : public ::testing::TestWithParam<ArcCase> {};

// v and w together, laser 0.25 m ahead, 0.05 m left and turned 0.1 rad on the base. Dense pose
// samples (every 0.5 ms) are exact here to well below 1 um.
TEST_P(ArcWithMountOffset, CorrectedErrorBelowATenthOfAMillimetre) {
  const ArcCase& param = GetParam();
  const sim::World world = sim::World::demoRoom();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, param.speed, param.yaw_rate);
  const Pose2 mount{0.25, 0.05, 0.1};
  const auto simulated = sim::simulateScan(world, arc, mount, param.model, kEpoch, 0.0);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 1.0 / param.model.rate + 0.01, 0.0005);
  for (const double knot_interval : {0.005, 0.0}) {
    for (const Reference reference : {Reference::kStart, Reference::kMiddle, Reference::kEnd}) {
      const CaseResult result =
          runCase(simulated, arc, mount, samples, withReference(reference, knot_interval));
      ASSERT_GT(result.scan.points.size(), static_cast<std::size_t>(param.model.beams) * 9 / 10);
      EXPECT_LT(result.corrected.max, 0.1 * kMm)
          << param.model.name << " knots " << knot_interval << " ref " << core::toString(reference);
      EXPECT_GT(result.raw.max, 100 * kMm);  // the distortion is real: decimetres
    }
  }
}

INSTANTIATE_TEST_SUITE_P(PaperSensors, ArcWithMountOffset,
                         ::testing::Values(ArcCase{LidarModel::utm30lx360(), 6.0, 5.0},
                                           ArcCase{LidarModel::ild26tri(), 6.0, 5.0},
                                           ArcCase{LidarModel::ild26tri(), 1.5, 2.0}));

// With a continuous motion source, knots every h and linear interpolation between them cut the arc's
// corners by at most the chord sagitta v w h^2 / 8 (rotation at constant rate is interpolated exactly).
TEST(Deskew, KnotsOnAContinuousArcStayWithinTheChordBound) {
  const sim::World world = sim::World::demoRoom();
  const double speed = 6.0, yaw_rate = 5.0, knot_interval = 0.005;
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, speed, yaw_rate);
  const Pose2 mount{0.25, 0.05, 0.1};
  const LidarModel model = LidarModel::ild26tri();
  const auto simulated = sim::simulateScan(world, arc, mount, model, kEpoch, 0.0);
  const test::ClosedFormMotion motion(arc, kEpoch, 0.0, 0.2);
  const CaseResult knots =
      runCase(simulated, arc, mount, motion, withReference(Reference::kStart, knot_interval));
  const CaseResult exact = runCase(simulated, arc, mount, motion, withReference(Reference::kStart, 0.0));
  const double sagitta = speed * yaw_rate * knot_interval * knot_interval / 8.0;  // 94 um
  EXPECT_LT(knots.corrected.max, sagitta + 0.001 * kMm);
  EXPECT_GT(knots.corrected.max, 0.2 * sagitta);  // the bound is tight: the error is really there
  EXPECT_LT(exact.corrected.max, 0.001 * kMm);
}

// Odometry at only 10 Hz on the 6 m/s, 5 rad/s arc: tf's straight line between samples is off the arc
// by up to v w h^2 / 8 = 7.5 mm; the twist between samples is the arc itself, so only the knots' chord
// (94 um at 5 ms) is left, and the exact mode (every beam from the fitted motion) has none.
TEST(Deskew, TwistInterpolationFollowsTheArcBetweenSparseSamples) {
  const sim::World world = sim::World::demoRoom();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const LidarModel model = LidarModel::ild26tri();
  const auto simulated = sim::simulateScan(world, arc, mount, model, kEpoch, 0.35);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.8, 0.1);
  const CaseResult linear = runCase(simulated, arc, mount, samples, withReference(Reference::kStart));
  const CaseResult knots = runCase(simulated, arc, mount, samples,
                                   withReference(Reference::kStart, 0.005, core::Interpolation::kTwist));
  const CaseResult exact = runCase(simulated, arc, mount, samples,
                                   withReference(Reference::kMiddle, 0.0, core::Interpolation::kTwist));
  EXPECT_GT(linear.corrected.max, 3.0 * kMm);
  EXPECT_LT(knots.corrected.max, 0.1 * kMm);
  EXPECT_LT(exact.corrected.max, 0.001 * kMm);
}

TEST(Deskew, ClockwiseScan) {
  LidarModel model = LidarModel::ild26tri();
  model.clockwise = true;
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 1.5, 2.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  ASSERT_LT(simulated.scan.angle_increment, 0.0f);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.13, 0.0005);
  const CaseResult result = runCase(simulated, arc, mount, samples, withReference(Reference::kStart));
  EXPECT_EQ(result.scan.points.size(), 360u);
  EXPECT_LT(result.corrected.max, 0.1 * kMm);
  EXPECT_GT(result.raw.max, 50 * kMm);
}

TEST(Deskew, Sensor270Degrees) {
  const LidarModel model = LidarModel::utm30lx270();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.03, 0.0005);
  const CaseResult result = runCase(simulated, arc, mount, samples, withReference(Reference::kStart));
  EXPECT_EQ(result.scan.points.size(), 1080u);
  EXPECT_LT(result.corrected.max, 0.1 * kMm);
  EXPECT_GT(result.raw.max, 20 * kMm);
}

TEST(Deskew, ZeroTimeIncrementFallsBackToScanTime) {
  const LidarModel model = LidarModel::ild26tri();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  simulated.scan.time_increment = 0.0f;  // the driver does not say; scan_time = 0.125 s
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.13, 0.0005);
  const CaseResult result = runCase(simulated, arc, mount, samples, withReference(Reference::kStart));
  EXPECT_LT(result.corrected.max, 0.1 * kMm);
}

TEST(Deskew, StampAtEnd) {
  const LidarModel model = LidarModel::ild26tri();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  simulated.scan.stamp += core::secondsToNs(359 * static_cast<double>(simulated.scan.time_increment));
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.13, 0.0005);
  core::TimingConfig timing;
  timing.stamp_at = core::StampAt::kEnd;
  const CaseResult result = runCase(simulated, arc, mount, samples, withReference(Reference::kStart), timing);
  EXPECT_LT(result.corrected.max, 0.1 * kMm);
  // Read as stamped at the start, the same scan is wrong by the whole sweep.
  const auto shifted = test::sampleTrajectory(arc, kEpoch, 0.0, 0.26, 0.0005);
  const CaseResult misread = runCase(simulated, arc, mount, shifted, withReference(Reference::kStart));
  EXPECT_GT(misread.corrected.max, 100 * kMm);
}

// Reference start and end re-express the same beams at different times: placed in the world with the
// laser's true pose at each reference time, both give the same (true) world points.
TEST(Deskew, ReferenceStartAndEndGiveTheSameWorldPoints) {
  const LidarModel model = LidarModel::ild26tri();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.13, 0.0005);
  const CaseResult start = runCase(simulated, arc, mount, samples, withReference(Reference::kStart));
  const CaseResult end = runCase(simulated, arc, mount, samples, withReference(Reference::kEnd));
  ASSERT_EQ(start.scan.points.size(), end.scan.points.size());
  const Pose2 laser_start = arc.pose(core::nsToSeconds(start.scan.reference_time - kEpoch)).compose(mount);
  const Pose2 laser_end = arc.pose(core::nsToSeconds(end.scan.reference_time - kEpoch)).compose(mount);
  double largest_in_frame_difference = 0.0;
  for (std::size_t j = 0; j < start.scan.points.size(); ++j) {
    const Eigen::Vector2d world_start = laser_start.apply(start.scan.points[j].position.head<2>());
    const Eigen::Vector2d world_end = laser_end.apply(end.scan.points[j].position.head<2>());
    EXPECT_LT((world_start - world_end).norm(), 0.1 * kMm);
    EXPECT_LT((world_start - simulated.world_hits[start.scan.points[j].beam_index]).norm(), 0.1 * kMm);
    largest_in_frame_difference = std::max(
        largest_in_frame_difference, (start.scan.points[j].position - end.scan.points[j].position).norm());
    // time offsets: to the start reference >= 0, to the end reference <= 0, 0.125 s apart at most
    EXPECT_GE(start.scan.points[j].time_offset, 0.0);
    EXPECT_LE(end.scan.points[j].time_offset, 1e-12);
  }
  EXPECT_GT(largest_in_frame_difference, 0.5);  // the two frames really differ
}

TEST(Deskew, MotionNotCoveringTheSweepThrowsAndLeavesNoPoints) {
  const LidarModel model = LidarModel::ild26tri();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 1.5, 2.0);
  const Pose2 mount{0.0, 0.0, 0.0};
  const auto simulated = sim::simulateScan(sim::World::demoRoom(), arc, mount, model, kEpoch, 0.0);
  const auto short_samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.1, 0.01);  // sweep lasts 0.1247 s
  for (const double knot_interval : {0.005, 0.0}) {
    ScanDeskewer deskewer(withReference(Reference::kStart, knot_interval));
    DeskewedScan out;
    EXPECT_THROW(deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), test::toMrpt(mount),
                                 short_samples, out),
                 core::MotionUnavailable);
    EXPECT_TRUE(out.points.empty());
  }
}

// Points with their own times (3D clouds): a 3D mount and motion with roll and pitch.
/// 0.2 s of 3D motion (translation, yaw, pitch, roll all changing), sampled every 10 ms.
core::PoseSamples movingIn3d() {
  core::PoseSamples samples;
  for (int k = 0; k <= 20; ++k) {
    const double t = 0.01 * k;
    samples.add(
        kEpoch + core::secondsToNs(t),
        mrpt::poses::CPose3D::FromXYZYawPitchRoll(3.0 * t, 0.5 * t * t, 0.2 * t, 2.0 * t, 0.3 * t, -0.4 * t));
  }
  return samples;
}

mrpt::poses::CPose3D tiltedMount() {
  return mrpt::poses::CPose3D::FromXYZYawPitchRoll(0.1, -0.2, 0.5, 0.3, 0.05, -0.1);
}

TEST(Deskew, PointsWithPerPointTimesMatchTheExactChain) {
  const core::PoseSamples samples = movingIn3d();
  const auto mount = tiltedMount();
  std::vector<Eigen::Vector3d> points;
  std::vector<double> offsets;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0), when(0.0, 0.2);
  for (int i = 0; i < 2000; ++i) {
    points.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    offsets.push_back(when(rng));
  }
  points[5].x() = NAN;  // skipped
  ScanDeskewer deskewer(withReference(Reference::kMiddle));
  std::vector<Eigen::Vector3d> corrected;
  std::vector<double> corrected_offsets;
  std::vector<std::uint32_t> kept;
  const TimeNs reference =
      deskewer.deskewPoints(points, offsets, kEpoch, mount, samples, corrected, corrected_offsets, kept);
  ASSERT_EQ(kept.size(), 1999u);
  for (std::size_t j = 0; j < kept.size(); ++j) {
    const std::uint32_t i = kept[j];
    const Eigen::Vector3d exact =
        core::deskewPointExact(points[i], kEpoch + core::secondsToNs(offsets[i]), reference, mount, samples);
    EXPECT_LT((corrected[j] - exact).norm(), 1e-6);  // 1 um: knots include every sample time
    EXPECT_NEAR(corrected_offsets[j], offsets[i] - core::nsToSeconds(reference - kEpoch), 1e-12);
  }
}

// A multi-line sensor fires a column of points at one time: the column's points share one affine map
// (KnotTrajectory::transformAt), and still land where the exact chain puts them. Columns given in
// order, and one point alone at its time (mapped directly).
TEST(Deskew, PointsSharingAFiringTimeMatchTheExactChain) {
  const core::PoseSamples samples = movingIn3d();
  const auto mount = tiltedMount();
  std::vector<Eigen::Vector3d> points;
  std::vector<double> offsets;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0);
  for (int column = 0; column < 300; ++column) {
    const int rings = column == 150 ? 1 : 16;  // one column of a single point
    for (int ring = 0; ring < rings; ++ring) {
      points.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
      offsets.push_back(0.2 * column / 299.0);
    }
  }
  ScanDeskewer deskewer(withReference(Reference::kStart));
  std::vector<Eigen::Vector3d> corrected;
  std::vector<double> corrected_offsets;
  std::vector<std::uint32_t> kept;
  const TimeNs reference =
      deskewer.deskewPoints(points, offsets, kEpoch, mount, samples, corrected, corrected_offsets, kept);
  ASSERT_EQ(kept.size(), points.size());
  double largest = 0.0;
  for (std::size_t j = 0; j < kept.size(); ++j) {
    const std::uint32_t i = kept[j];
    const Eigen::Vector3d exact =
        core::deskewPointExact(points[i], kEpoch + core::secondsToNs(offsets[i]), reference, mount, samples);
    largest = std::max(largest, (corrected[j] - exact).norm());
  }
  EXPECT_LT(largest, 1e-6);  // 1 um, as point by point
}

}  // namespace
}  // namespace lidar_deskew

namespace lidar_deskew {
namespace {

// The planar fast path (a rotation step per beam) and the general knot map give the same points, for
// forward and backward beam timing.
TEST(Deskew, PlanarFastPathMatchesTheGeneralKnotMap) {
  const sim::World world = sim::World::demoRoom();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  const LidarModel model = LidarModel::ild26tri();
  // Beams without a return (all kinds, alone and in runs, at the ends) are left out, the rest kept in order.
  const float nan = std::numeric_limits<float>::quiet_NaN(), infinity = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<std::size_t, float>> misses = {
      {0, 0.0f}, {3, nan}, {4, infinity}, {5, 2.0f * model.range_max}, {17, -1.0f}, {359, nan}};
  for (const int variant : {0, 1, 2}) {
    const bool backwards = variant == 1;
    auto simulated = sim::simulateScan(world, arc, mount, model, kEpoch, 0.0);
    if (backwards) {  // same ranges, but the driver says beam 0 came last
      simulated.scan.time_increment = -simulated.scan.time_increment;
    }
    std::vector<std::uint32_t> returns;
    if (variant == 2) {
      for (const auto& [beam, range] : misses)
        simulated.scan.ranges[beam] = range;
      for (std::size_t beam = 64; beam < 80; ++beam)
        simulated.scan.ranges[beam] = infinity;
    }
    for (std::uint32_t beam = 0; beam < 360; ++beam) {
      const float range = simulated.scan.ranges[beam];
      if (range >= simulated.scan.range_min && range <= simulated.scan.range_max)
        returns.push_back(beam);
    }
    const test::ClosedFormMotion motion(arc, kEpoch, -0.2, 0.2);
    const core::BeamTiming timing = core::resolveTiming(simulated.scan, {});
    ScanDeskewer deskewer(withReference(Reference::kMiddle));
    DeskewedScan fast;
    deskewer.deskew(simulated.scan, timing, test::toMrpt(mount), motion, fast);
    ASSERT_EQ(fast.points.size(), variant == 2 ? 360u - 22u : 360u);
    ASSERT_EQ(fast.points.size(), returns.size());
    for (std::size_t i = 0; i < returns.size(); ++i)
      ASSERT_EQ(fast.points[i].beam_index, returns[i]);

    core::KnotTrajectory general;
    const double last = timing.beamOffset(359);
    general.build(timing.first_beam_time, std::min(0.0, last), std::max(0.0, last), fast.reference_time,
                  0.005, test::toMrpt(mount), motion);
    ASSERT_TRUE(general.planar());
    EXPECT_GE(general.knotCount(), 26u);  // 0.125 s sweep, 5 ms knots
    double largest = 0.0;
    for (const auto& point : fast.points) {
      const double angle =
          simulated.scan.angle_min + point.beam_index * static_cast<double>(simulated.scan.angle_increment);
      const double range = simulated.scan.ranges[point.beam_index];
      const Eigen::Vector3d expected = general.apply(timing.beamOffset(point.beam_index),
                                                     {range * std::cos(angle), range * std::sin(angle), 0.0});
      largest = std::max(largest, (point.position - expected).norm());
      EXPECT_NEAR(point.time_offset,
                  timing.beamOffset(point.beam_index) -
                      core::nsToSeconds(fast.reference_time - timing.first_beam_time),
                  1e-12);
    }
    EXPECT_LT(largest, 1e-9) << "variant " << variant;
  }
}

// A laser tilted on its mount (roll, pitch) leaves the planar path: points leave the plane z = 0 of the
// base, and the general knot map still matches the exact per-beam chain.
TEST(Deskew, TiltedMountMatchesTheExactChain) {
  const sim::World world = sim::World::demoRoom();
  const ArcTrajectory arc({-1.0, -0.5, 0.3}, 6.0, 5.0);
  const Pose2 planar_mount{0.25, 0.05, 0.1};
  const LidarModel model = LidarModel::utm30lx360();
  const auto simulated = sim::simulateScan(world, arc, planar_mount, model, kEpoch, 0.0);
  const auto tilted = mrpt::poses::CPose3D::FromXYZYawPitchRoll(0.25, 0.05, 0.3, 0.1, 0.05, 0.08);
  const auto samples = test::sampleTrajectory(arc, kEpoch, 0.0, 0.03, 0.02);
  const core::BeamTiming timing = core::resolveTiming(simulated.scan, {});
  DeskewedScan knots, exact;
  ScanDeskewer(withReference(Reference::kStart)).deskew(simulated.scan, timing, tilted, samples, knots);
  ScanDeskewer(withReference(Reference::kStart, 0.0)).deskew(simulated.scan, timing, tilted, samples, exact);
  ASSERT_EQ(knots.points.size(), exact.points.size());
  double largest = 0.0, largest_z = 0.0;
  for (std::size_t j = 0; j < knots.points.size(); ++j) {
    largest = std::max(largest, (knots.points[j].position - exact.points[j].position).norm());
    largest_z = std::max(largest_z, std::abs(exact.points[j].position.z()));
  }
  EXPECT_LT(largest, 1e-6);    // 1 um: the knots include every pose sample, so both follow tf's lerp
  EXPECT_GT(largest_z, 1e-3);  // the tilt really moves points out of the scan plane
}

}  // namespace
}  // namespace lidar_deskew
