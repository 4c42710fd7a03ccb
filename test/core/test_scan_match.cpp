// The free rigid scan match against the simulator's known poses, and the shape measure and the rotation
// check on a simulated drive with known timing and odometry (docs/CALIBRATION.md, "Shapes").
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "lidar_deskew/core/scan_match.h"
#include "lidar_deskew/sim/sim.h"
#include "../support/turning_drive.h"

namespace lidar_deskew::core {
namespace {

constexpr TimeNs kEpoch = 1'700'000'000'000'000'000;
constexpr double kDegree = M_PI / 180.0;

/// A scan of `world` from `pose`, every beam at once: its returns in the laser frame, beam order.
std::vector<Eigen::Vector2d> snapshot(const sim::World& world, const sim::Pose2& pose, int beams) {
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < beams; ++i) {
    const double bearing = -M_PI + 2.0 * M_PI * i / beams;
    const Eigen::Vector2d direction(std::cos(pose.yaw + bearing), std::sin(pose.yaw + bearing));
    if (const auto range = world.castRay({pose.x, pose.y}, direction); range && *range < 30.0)
      points.emplace_back(*range * std::cos(bearing), *range * std::sin(bearing));
  }
  return points;
}

TEST(ScanMatch, RecoversARigidMoveWithoutAGuess) {
  const sim::World world = sim::World::demoRoom();
  const sim::Pose2 reference_pose{0.4, -0.3, 0.2};
  const std::vector<Eigen::Vector2d> reference_points = snapshot(world, reference_pose, 360);
  const PlacedScan reference(0, Eigen::Vector2d::Zero(), 2.0 * M_PI / 360, reference_points);
  // Moves in the reference laser's frame, up to 0.3 m and 20 degrees, both ways; and 40 degrees, which
  // the iterations alone do not find (the coarse search over rotations does).
  const sim::Pose2 moves[] = {{0.3, 0.0, 0.0},
                              {0.0, -0.3, 0.0},
                              {0.0, 0.0, 20 * kDegree},
                              {0.21, -0.2, -20 * kDegree},
                              {-0.25, 0.15, 17 * kDegree},
                              {0.1, 0.28, -12 * kDegree},
                              {0.2, 0.1, 40 * kDegree},
                              {-0.1, -0.2, -40 * kDegree}};
  for (const sim::Pose2& move : moves) {
    const sim::Pose2 moving_pose = reference_pose.compose(move);
    const ScanMatch match = matchScans(reference, snapshot(world, moving_pose, 360), Pose2d());
    ASSERT_TRUE(match.valid) << move.x << " " << move.y << " " << move.yaw;
    EXPECT_NEAR(match.pose.x, move.x, 0.001) << move.x << " " << move.y << " " << move.yaw;
    EXPECT_NEAR(match.pose.y, move.y, 0.001) << move.x << " " << move.y << " " << move.yaw;
    EXPECT_NEAR(match.pose.yaw, move.yaw, 0.05 * kDegree) << move.x << " " << move.y << " " << move.yaw;
    EXPECT_LT(match.distance, 0.001);
    EXPECT_GT(match.overlap, 0.8);
  }
}

using Drive = test_support::TurningDrive;

/// The drive's scans with range noise (`reversed`: beams measured against the index order the
/// message claims; stamps `stamp_delay` [s] after the first beam) and odometry at 50 Hz whose yaw
/// increments are the true ones x `yaw_scale`.
using Recording = test_support::TurningRecording;
Recording record(const Drive& drive, bool reversed, double yaw_scale, double stamp_delay = 0.0) {
  Recording recording;
  const sim::World world = sim::World::hall();
  sim::LidarModel lidar = drive.lidar;
  lidar.range_sigma = 0.01;  // [m] a Hokuyo's: the shapes, not the noise, dominate the distances
  if (reversed)
    lidar.clockwise = !lidar.clockwise;
  std::mt19937 random(7);
  for (double t = 0.0; t < drive.duration; t += 1.0 / lidar.rate) {
    sim::SimulatedScan simulated =
        sim::simulateScan(world, drive.trajectory, drive.mount, lidar, kEpoch, t, &random);
    PlanarScan& scan = simulated.scan;
    if (reversed) {
      std::reverse(scan.ranges.begin(), scan.ranges.end());
      scan.angle_min =
          static_cast<float>(scan.angle_min + (scan.ranges.size() - 1) * double(scan.angle_increment));
      scan.angle_increment = -scan.angle_increment;
      scan.time_increment = std::abs(scan.time_increment);
    }
    scan.stamp += secondsToNs(stamp_delay);
    recording.scans.push_back(scan);
  }
  sim::Pose2 odometry = drive.trajectory.pose(-1.0);
  for (double t = -1.0; t < drive.duration + 1.0; t += 0.02) {
    recording.motion.add(kEpoch + secondsToNs(t), mrpt::poses::CPose2D(odometry.x, odometry.y, odometry.yaw));
    sim::Pose2 step = drive.trajectory.pose(t).between(drive.trajectory.pose(t + 0.02));
    step.yaw *= yaw_scale;
    odometry = odometry.compose(step);
  }
  recording.mount = mrpt::poses::CPose3D(drive.mount.x, drive.mount.y, 0.0, drive.mount.yaw, 0.0, 0.0);
  return recording;
}

TEST(ShapeCheck, RightTimingSharpensShapesWrongBeamOrderBlursThem) {
  const Drive drive;
  const Recording right = record(drive, false, 1.0);
  const ShapeCheck check(right.scans, right.mount, right.motion);
  const ShapeRatio shapes = check.shapes(TimingConfig());
  ASSERT_GE(shapes.pairs, 30u);
  EXPECT_LT(shapes.ratio, 0.6);
  // Perfect odometry: the matched rotation is tf's between the sweeps' middles, at lag 0.
  EXPECT_NEAR(check.rotation().scale, 1.0, 0.03);
  EXPECT_GT(check.rotation().correlation, 0.99);
  EXPECT_NEAR(check.rotation().lag, 0.0, 0.015);
  EXPECT_GE(check.rotation().turning_pairs, 30u);
  EXPECT_TRUE(shapeWarnings(shapes, check.rotation()).empty());

  // The beams measured last to first, the message (and so the timing) claiming index order.
  const Recording reversed = record(drive, true, 1.0);
  const ShapeCheck reversed_check(reversed.scans, reversed.mount, reversed.motion);
  const ShapeRatio wrong = reversed_check.shapes(TimingConfig());
  ASSERT_GE(wrong.pairs, 30u);
  EXPECT_GT(wrong.ratio, 1.2);
  TimingConfig fixed;
  fixed.beam_order = BeamOrder::kReversed;
  EXPECT_LT(reversed_check.shapes(fixed).ratio, 0.6);
  const std::vector<std::string> warnings = shapeWarnings(wrong, reversed_check.rotation());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("correction makes shapes worse than raw"), std::string::npos) << warnings[0];
}

TEST(ShapeCheck, SeesOdometryThatTurnsTooLittle) {
  const Drive drive;
  const Recording recording = record(drive, false, 0.4);
  const ShapeCheck check(recording.scans, recording.mount, recording.motion);
  // Scan matching sees the true rotation: 1 / 0.4 of tf's.
  EXPECT_NEAR(check.rotation().scale, 2.5, 0.1);
  EXPECT_GT(check.rotation().correlation, 0.99);
  const ShapeRatio shapes = check.shapes(TimingConfig());
  const std::vector<std::string> warnings = shapeWarnings(shapes, check.rotation());
  ASSERT_GE(warnings.size(), 1u);
  char figure[64];
  std::snprintf(figure, sizeof figure, "scan matching sees %.2fx tf's rotation", check.rotation().scale);
  EXPECT_EQ(warnings[0].find("tf's rotation does not fit the scans"), 0u) << warnings[0];
  EXPECT_NE(warnings[0].find(figure), std::string::npos) << warnings[0];
}

TEST(ShapeCheck, SeesWhenTfFitsOnlyAtAnotherTime) {
  // Stamped with the last beam, the message claiming the first: tf's rotation fits the scans a sweep
  // earlier than the stamps say (124.7 ms: 359 beams); with stamp_at end it fits at lag 0.
  const Drive drive;
  const double sweep = 359.0 / (360.0 * drive.lidar.rate);
  const Recording at_end = record(drive, false, 1.0, sweep);
  const ShapeCheck check(at_end.scans, at_end.mount, at_end.motion);
  EXPECT_NEAR(check.rotation().lag, -sweep, 0.006);
  EXPECT_NEAR(check.rotation().lag_scale, 1.0, 0.03);
  EXPECT_GT(check.rotation().lag_correlation, 0.99);
  TimingConfig end;
  end.stamp_at = StampAt::kEnd;
  const RotationAgreement fits = check.rotation(end);
  EXPECT_NEAR(fits.lag, 0.0, 0.006);
  EXPECT_NEAR(fits.scale, 1.0, 0.03);
  EXPECT_GT(fits.correlation, 0.99);
  EXPECT_TRUE(shapeWarnings(check.shapes(end), fits).empty());

  // Stamps 400 ms late: at the stamps tf's rotation does not fit the scans; 400 ms earlier it does,
  // and the warning says so.
  const Recording late = record(drive, false, 1.0, 0.4);
  const ShapeCheck late_check(late.scans, late.mount, late.motion);
  EXPECT_NEAR(late_check.rotation().lag, -0.4, 0.006);
  EXPECT_GT(late_check.rotation().lag_correlation, 0.99);
  const std::vector<std::string> warnings =
      shapeWarnings(late_check.shapes(TimingConfig()), late_check.rotation());
  ASSERT_GE(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("tf read at the scans' times -400 ms fits"), std::string::npos) << warnings[0];
}

// The live node's monitor, fed scan after scan as the node feeds them: a pair every 0.3 s.
TEST(RotationMonitor, SeesTfsRotationFitOrNot) {
  const Drive drive;
  RotationMonitorConfig config;
  config.interval = 0.3;
  for (const double yaw_scale : {1.0, 0.4}) {
    const Recording recording = record(drive, false, yaw_scale);
    RotationMonitor monitor(TimingConfig(), config);
    std::size_t matched = 0;
    for (const PlanarScan& scan : recording.scans)
      matched += monitor.add(scan, recording.mount, recording.motion) ? 1 : 0;
    const RotationAgreement agreement = monitor.agreement();
    EXPECT_GE(matched, 25u);
    EXPECT_LE(matched, 34u);  // one in three scans at most (8 Hz)
    EXPECT_GE(agreement.turning_pairs, 10u);
    EXPECT_NEAR(agreement.scale, 1.0 / yaw_scale, 0.05 / yaw_scale) << yaw_scale;
    EXPECT_GT(agreement.correlation, 0.99) << yaw_scale;
    EXPECT_EQ(monitor.warnings().empty(), yaw_scale == 1.0) << yaw_scale;
    monitor.reset(TimingConfig());
    EXPECT_EQ(monitor.agreement().pairs, 0u);
  }
}

}  // namespace
}  // namespace lidar_deskew::core
