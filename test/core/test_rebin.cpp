// Re-binning onto the input grid as rays (docs/DESIGN.md §4), against closed-form geometry. Tolerances in mm.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "lidar_deskew/core/rebin.h"
#include "support/truth.h"

namespace lidar_deskew {
namespace {

using core::DeskewedScan;
using core::RebinnedScan;
using core::ScanRebinner;
using core::TimeNs;
using sim::ArcTrajectory;
using sim::LidarModel;
using sim::Pose2;

using test::kEpoch;
using test::kMm;
constexpr float kInf = std::numeric_limits<float>::infinity();

core::AngleGrid gridOf(const core::PlanarScan& scan) {
  return {scan.angle_min, scan.angle_increment, scan.ranges.size()};
}

DeskewedScan deskew(const sim::SimulatedScan& simulated, const sim::Trajectory& trajectory,
                    const Pose2& mount) {
  const auto samples =
      test::sampleTrajectory(trajectory, kEpoch, 0.0, simulated.beam_times.back() + 0.01, 0.0005);
  core::ScanDeskewer deskewer;
  DeskewedScan out;
  deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), test::toMrpt(mount), samples, out);
  return out;
}

TEST(Rebin, StaticRobotReproducesTheInputScan) {
  const ArcTrajectory still({1.0, -0.5, 0.7}, 0.0, 0.0);
  const Pose2 mount{0.25, 0.05, 0.1};
  auto simulated =
      sim::simulateScan(sim::World::demoRoom(), still, mount, LidarModel::ild26tri(), kEpoch, 0.0);
  simulated.scan.intensities.resize(simulated.scan.ranges.size());
  for (std::size_t i = 0; i < simulated.scan.ranges.size(); ++i)
    simulated.scan.intensities[i] = 100.0f + i;
  for (std::size_t i = 40; i < 60; i += 3)
    simulated.scan.ranges[i] = 0.0f;  // dropouts -> lone returns
  const DeskewedScan corrected = deskew(simulated, still, mount);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(corrected, gridOf(simulated.scan), core::noReturnValue(simulated.scan), out);
  ASSERT_EQ(out.ranges.size(), simulated.scan.ranges.size());
  ASSERT_EQ(out.intensities.size(), simulated.scan.ranges.size());
  for (std::size_t i = 0; i < out.ranges.size(); ++i) {
    EXPECT_NEAR(out.ranges[i], simulated.scan.ranges[i], 1e-5) << "bin " << i;
    if (simulated.scan.ranges[i] > 0.0f) {
      EXPECT_NEAR(out.intensities[i], simulated.scan.intensities[i], 1e-3);
    }
  }
}

// A grid of 361 beams of 1 deg (like the Neato XV-11's) has its first and last beam on the same ray.
TEST(Rebin, GridWiderThanATurnFillsBothEnds) {
  LidarModel model = LidarModel::ild26tri();
  model.beams = 361;
  model.field_of_view = 361.0 * M_PI / 180.0;
  const ArcTrajectory still({1.0, -0.5, 0.7}, 0.0, 0.0);
  const Pose2 mount{0.0, 0.0, 0.0};
  const auto simulated = sim::simulateScan(sim::World::demoRoom(), still, mount, model, kEpoch, 0.0);
  const DeskewedScan corrected = deskew(simulated, still, mount);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(corrected, gridOf(simulated.scan), core::noReturnValue(simulated.scan), out);
  ASSERT_EQ(out.ranges.size(), 361u);
  for (std::size_t i = 0; i < out.ranges.size(); ++i) {
    EXPECT_NEAR(out.ranges[i], simulated.scan.ranges[i], 1e-5) << "bin " << i;
  }
  EXPECT_NEAR(out.ranges[0], out.ranges[360], 1e-5);
}

// A straight wall seen while spinning and driving: every re-binned beam's endpoint (ray at the bin's
// angle, at its range, from the laser's true pose at t_ref) lies on the true wall.
TEST(Rebin, EndpointsOfEveryBinLieOnTheTrueWall) {
  sim::World world;
  world.add({-200.0, 2.0}, {200.0, 2.0});  // the line y = 2
  for (const LidarModel& base_model : {LidarModel::ild26tri(), LidarModel::utm30lx360()}) {
    LidarModel model = base_model;
    model.range_max = 8.0f;  // walls beyond are out of range; incidence stays below 76 deg
    const ArcTrajectory spin({0.0, 0.0, 0.4}, 1.5, 5.0);
    const Pose2 mount{0.25, 0.05, 0.1};
    const auto simulated = sim::simulateScan(world, spin, mount, model, kEpoch, 0.0);
    const DeskewedScan corrected = deskew(simulated, spin, mount);
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(corrected, gridOf(simulated.scan), core::noReturnValue(simulated.scan), out);
    ASSERT_EQ(out.ranges.size(), static_cast<std::size_t>(model.beams));

    const Pose2 laser = spin.pose(core::nsToSeconds(corrected.reference_time - kEpoch)).compose(mount);
    std::size_t finite_bins = 0;
    double worst = 0.0, worst_snapped = 0.0;
    for (std::size_t b = 0; b < out.ranges.size(); ++b) {
      if (!std::isfinite(out.ranges[b]))
        continue;
      ++finite_bins;
      const double angle = simulated.scan.angle_min + b * static_cast<double>(simulated.scan.angle_increment);
      const Eigen::Vector2d endpoint =
          laser.apply(out.ranges[b] * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
      worst = std::max(worst, std::abs(endpoint.y() - 2.0));
    }
    // For comparison: snapping each corrected point to its nearest bin at its own range.
    for (const auto& point : corrected.points) {
      const core::PolarPoint polar = core::toPolar(point.position);
      const double bin =
          std::round((polar.bearing - simulated.scan.angle_min) / simulated.scan.angle_increment);
      const double angle = simulated.scan.angle_min + bin * simulated.scan.angle_increment;
      const Eigen::Vector2d endpoint =
          laser.apply(polar.range * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
      worst_snapped = std::max(worst_snapped, std::abs(endpoint.y() - 2.0));
    }
    EXPECT_LT(worst, 0.5 * kMm) << model.name;
    EXPECT_GT(worst_snapped, 5 * kMm) << model.name;  // what snapping would have cost

    // Coverage: every bin whose ray (from the laser at t_ref) meets the part of the wall the scan saw
    // has a range; at most one bin at each end of that part may be missed.
    double seen_min_x = INFINITY, seen_max_x = -INFINITY;
    for (const auto& point : corrected.points) {
      seen_min_x = std::min(seen_min_x, simulated.world_hits[point.beam_index].x());
      seen_max_x = std::max(seen_max_x, simulated.world_hits[point.beam_index].x());
    }
    std::size_t expected_bins = 0, missed_bins = 0;
    for (std::size_t b = 0; b < out.ranges.size(); ++b) {
      const double angle =
          laser.yaw + simulated.scan.angle_min + b * static_cast<double>(simulated.scan.angle_increment);
      const auto hit = world.castRay({laser.x, laser.y}, {std::cos(angle), std::sin(angle)});
      if (!hit)
        continue;
      const double x = laser.x + *hit * std::cos(angle);
      if (x < seen_min_x || x > seen_max_x)
        continue;
      ++expected_bins;
      if (!std::isfinite(out.ranges[b]))
        ++missed_bins;
    }
    EXPECT_GT(expected_bins, static_cast<std::size_t>(model.beams) / 4) << model.name;
    EXPECT_LE(missed_bins, 2u) << model.name;
    EXPECT_LE(finite_bins, expected_bins + 2) << model.name;
  }
}

// Synthetic corrected scans on a 1 deg grid: positions given in closed form.
struct SyntheticScan {
  DeskewedScan scan;
  core::AngleGrid grid{static_cast<float>(-M_PI), static_cast<float>(M_PI / 180.0), 360};

  /// Points on the line x = distance at bearings first_deg .. last_deg (1 deg apart), beam indices from
  /// first_index, with `intensity`.
  void addLine(double distance, int first_deg, int last_deg, std::uint32_t first_index, float intensity) {
    scan.has_intensities = true;
    for (int degrees = first_deg; degrees <= last_deg; ++degrees) {
      const double bearing = degrees * M_PI / 180.0;
      scan.points.push_back({Eigen::Vector3d(distance, distance * std::tan(bearing), 0.0), 0.0, intensity,
                             first_index + static_cast<std::uint32_t>(degrees - first_deg)});
    }
  }
  static int binOf(int degrees) { return degrees + 180; }
};

/// Beams at bearings (k + 0.5) deg, k = first_deg .. last_deg, ray-cast from the origin into `world`
/// (half a bin off the 1 deg grid, so every bin's ray passes between two returns); beam indices from 0.
/// (`offset_deg` instead of 0.5 moves the beams off the midpoints.)
DeskewedScan castHalfBinBeams(const sim::World& world, int first_deg, int last_deg, double offset_deg = 0.5) {
  DeskewedScan scan;
  for (int k = first_deg; k <= last_deg; ++k) {
    const double bearing = (k + offset_deg) * M_PI / 180.0;
    const Eigen::Vector2d direction(std::cos(bearing), std::sin(bearing));
    const auto range = world.castRay({0.0, 0.0}, direction);
    if (range) {
      scan.points.push_back({Eigen::Vector3d(*range * direction.x(), *range * direction.y(), 0.0), 0.0, 0.0f,
                             static_cast<std::uint32_t>(k - first_deg)});
    }
  }
  return scan;
}

/// Every bin from first_deg to last_deg holds the range where its ray first meets `world` (within
/// 0.1 mm), or no return where `may_be_empty` allows; returns how many bins are filled.
int expectTrueRanges(const sim::World& world, const RebinnedScan& out, int first_deg, int last_deg,
                     bool may_be_empty) {
  int filled = 0;
  for (int degrees = first_deg; degrees <= last_deg; ++degrees) {
    const double angle = degrees * M_PI / 180.0;
    const auto truth = world.castRay({0.0, 0.0}, {std::cos(angle), std::sin(angle)});
    const float range = out.ranges[degrees + 180];
    if (std::isinf(range) && may_be_empty)
      continue;
    ++filled;
    EXPECT_TRUE(truth) << degrees;
    EXPECT_NEAR(range, truth.value_or(-1.0), 0.1 * kMm) << degrees << " deg";
  }
  return filled;
}

const core::AngleGrid kDegreeGrid{static_cast<float>(-M_PI), static_cast<float>(M_PI / 180.0), 360};

// A concave and a convex corner between two beams: the rays between meet the walls up to the corner
// (a chord between the two returns would cut 5-9 mm into the room or the block).
TEST(Rebin, CornersBetweenTwoBeamsGiveTheCornersRange) {
  sim::World room;  // the walls x = 4 and y = 1 meet at (4, 1), bearing 14.04 deg, 4.1 m away
  room.add({4.0, -2.0}, {4.0, 1.0});
  room.add({4.0, 1.0}, {-2.0, 1.0});
  sim::World block;  // a block's corner at (3, 0) pointing at the sensor: faces towards -y and +y
  block.add({3.0, 0.0}, {4.0, -1.5});
  block.add({3.0, 0.0}, {4.0, 1.5});
  struct Case {
    const sim::World& world;
    int first_deg, last_deg;  // the beams' half-degree bearings; the bins between are checked
  };
  for (const Case& c : {Case{room, -15, 40}, Case{block, -20, 19}}) {
    const DeskewedScan scan = castHalfBinBeams(c.world, c.first_deg, c.last_deg);
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(scan, kDegreeGrid, kInf, out);
    EXPECT_EQ(expectTrueRanges(c.world, out, c.first_deg + 1, c.last_deg, false), c.last_deg - c.first_deg);
  }
  // The room's corner bin in numbers: 4 / cos(14 deg) = 4.1224 m; the chord gives 4.1168 m.
  const DeskewedScan scan = castHalfBinBeams(room, -15, 40);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  EXPECT_NEAR(out.ranges[14 + 180], 4.0 / std::cos(14.0 * M_PI / 180.0), 0.1 * kMm);
}

// A corner far away (20 m) between a wall facing the sensor and one leaving it at a grazing angle (80 deg
// off-normal: its returns 2-4 m apart, farther than the gap, so not joined): the rays between meet the
// facing wall up to the corner and the grazing one beyond, not the grazing wall's line continued in
// front of the facing one (0.5 m off at bin 6 deg).
TEST(Rebin, CornerOfAFarGrazingWall) {
  const double corner_deg = 6.3;
  const Eigen::Vector2d corner(20.0, 20.0 * std::tan(corner_deg * M_PI / 180.0));
  const double wall_deg = corner_deg + 10.0;  // the grazing wall's direction: 10 deg off the corner's ray
  sim::World world;
  world.add({20.0, -8.0}, corner);
  world.add(corner, corner + 60.0 * Eigen::Vector2d(std::cos(wall_deg * M_PI / 180.0),
                                                    std::sin(wall_deg * M_PI / 180.0)));
  const DeskewedScan scan = castHalfBinBeams(world, -20, 12);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  EXPECT_EQ(expectTrueRanges(world, out, -19, 12, false), 32);
  EXPECT_NEAR(out.ranges[6 + 180], 20.0 / std::cos(6.0 * M_PI / 180.0), 0.1 * kMm);  // the facing wall
}

// A far wall at a grazing angle whose first return has no return before it: that return is not flat (one
// neighbour), the next one is (the three on one line), so the two are one surface although farther apart
// than the gap. The ray before the first return (6 deg; the wall begins at 5.8) would meet the wall's line
// 0.9 m before that return, but the returns cannot tell where the wall begins (anywhere from 5.5 to 6.5
// deg): the bin is left empty, neither guessed on the line nor a facet facing the sensor (0.5 m off).
TEST(Rebin, FarGrazingWallFromItsFirstReturn) {
  const Eigen::Vector2d start(20.0, 20.0 * std::tan(5.8 * M_PI / 180.0));  // bearing 5.8 deg
  const double wall_deg = 15.8;                                            // 10 deg off that ray
  sim::World world;
  world.add(start, start + 60.0 * Eigen::Vector2d(std::cos(wall_deg * M_PI / 180.0),
                                                  std::sin(wall_deg * M_PI / 180.0)));
  const DeskewedScan scan = castHalfBinBeams(world, 0, 12);  // returns from 6.5 deg on
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  EXPECT_EQ(expectTrueRanges(world, out, 7, 12, false), 6);
  EXPECT_TRUE(std::isinf(out.ranges[6 + 180]));  // where the wall begins cannot be told: empty
  EXPECT_TRUE(std::isinf(out.ranges[5 + 180]));  // before the wall: nothing
}

// A near wall ends and a far one continues behind it, the two joined (15 cm apart) or not (4 m apart):
// the ray past the near end sees the far wall (or nothing), never a point on the chord between them.
TEST(Rebin, OcclusionEdgeGivesTheFarWallNeverFreeSpace) {
  for (const double far_x : {2.15, 6.0}) {
    sim::World world;
    world.add({2.0, -2.0}, {2.0, 0.2});      // near wall ends at bearing 5.71 deg
    world.add({far_x, -5.0}, {far_x, 5.0});  // far wall behind it
    const DeskewedScan scan = castHalfBinBeams(world, -20, 30);
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(scan, kDegreeGrid, kInf, out);
    expectTrueRanges(world, out, -19, 30, true);
    // Bin 6 deg lies between the near wall's last return (5.5 deg) and the far wall's first (6.5 deg).
    EXPECT_NEAR(out.ranges[6 + 180], far_x / std::cos(6.0 * M_PI / 180.0), 0.1 * kMm) << far_x;
  }
}

/// `scan` with every return's range moved by +noise, -noise, +noise, ... [m] (a zig-zag: the worst case
/// for a line through two neighbouring returns).
DeskewedScan withZigZagNoise(DeskewedScan scan, double noise) {
  double sign = 1.0;
  for (auto& point : scan.points) {
    const double range = point.position.head<2>().norm();
    point.position.head<2>() *= (range + sign * noise) / range;
    sign = -sign;
  }
  return scan;
}

/// Every filled bin from first_deg to last_deg lies within `margin` [m] of the range interval of the two
/// returns around it (at bearings bin -+ 0.5 deg, cast into `world`): no rule extrapolates past them.
void expectBetweenNeighbours(const sim::World& world, const RebinnedScan& out, int first_deg, int last_deg,
                             double margin) {
  for (int degrees = first_deg; degrees <= last_deg; ++degrees) {
    const float range = out.ranges[degrees + 180];
    if (std::isinf(range))
      continue;
    double low = kInf, high = 0.0;
    for (const double bearing_deg : {degrees - 0.5, degrees + 0.5}) {
      const double bearing = bearing_deg * M_PI / 180.0;
      const auto hit = world.castRay({0.0, 0.0}, {std::cos(bearing), std::sin(bearing)});
      ASSERT_TRUE(hit) << bearing_deg;
      low = std::min(low, *hit);
      high = std::max(high, *hit);
    }
    EXPECT_GE(range, low - margin) << degrees << " deg";
    EXPECT_LE(range, high + margin) << degrees << " deg";
  }
}

// The occlusion edge with +-20 mm of zig-zag range noise: the far wall's end segment is then no evidence
// for where the wall runs behind the near one (continued, it would go tens of cm astray), so the step is
// joined as without the continuation; no bin leaves the range interval of its two returns by more than
// twice the noise (a contour end follows its noisy end segment for half a bin).
TEST(Rebin, NoisyOcclusionEdgeIsNotContinued) {
  constexpr double kNoise = 0.02;  // [m]
  for (const double far_x : {2.15, 6.0}) {
    sim::World world;
    world.add({2.0, -2.0}, {2.0, 0.2});
    world.add({far_x, -5.0}, {far_x, 5.0});
    const DeskewedScan scan = withZigZagNoise(castHalfBinBeams(world, -20, 30), kNoise);
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(scan, kDegreeGrid, kInf, out);
    expectBetweenNeighbours(world, out, -19, 30, 2.0 * kNoise + 1.0 * kMm);
  }
}

// A 10 cm wide post 2 m away in front of a wall 6 m away, the post's first return 0.05 deg past bin 8
// (the post starts at 7.97 deg), +-20 mm of zig-zag noise: bin 8 sees the post. Continuing the noisy far
// wall behind the post's return would give it the wall, 4 m off.
TEST(Rebin, NoisyStepKeepsTheNearReturnsOwnBin) {
  constexpr double kNoise = 0.02;  // [m]
  sim::World world;
  world.add({2.0, 0.28}, {2.0, 0.38});
  world.add({6.0, -5.0}, {6.0, 5.0});
  const DeskewedScan scan = withZigZagNoise(castHalfBinBeams(world, -20, 30, 0.05), kNoise);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  EXPECT_NEAR(out.ranges[8 + 180], 2.0 / std::cos(8.0 * M_PI / 180.0), 2.0 * kNoise + 1.0 * kMm);
}

// A wall seen at a grazing angle, its returns farther apart than the gap, with +-20 mm of zig-zag noise:
// with that much noise two "flat" returns are no evidence of one surface, so they are not joined beyond
// the gap (as without the grazing join); the bins stay within twice the noise of their returns' ranges.
TEST(Rebin, NoisyGrazingWallIsNotJoinedBeyondTheGap) {
  constexpr double kNoise = 0.02;  // [m]
  sim::World world;
  world.add({0.3, 0.5}, {12.0, 1.2});  // nearly along the rays: returns ~0.3 .. 0.9 m apart
  const DeskewedScan scan = withZigZagNoise(castHalfBinBeams(world, 6, 40), kNoise);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  expectBetweenNeighbours(world, out, 7, 40, 2.0 * kNoise + 1.0 * kMm);
}

// A 0.4 m square pillar 3 m ahead of a wall 5 m away: its face and the wall on both sides, exact.
TEST(Rebin, PillarInFrontOfAWall) {
  sim::World world;
  world.addPolygon({{3.0, -0.2}, {3.4, -0.2}, {3.4, 0.2}, {3.0, 0.2}});
  world.add({5.0, -5.0}, {5.0, 5.0});
  const DeskewedScan scan = castHalfBinBeams(world, -30, 30);
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(scan, kDegreeGrid, kInf, out);
  EXPECT_EQ(expectTrueRanges(world, out, -29, 29, false), 59);
  EXPECT_NEAR(out.ranges[3 + 180], 3.0 / std::cos(3.0 * M_PI / 180.0), 0.1 * kMm);  // the pillar
  EXPECT_NEAR(out.ranges[4 + 180], 5.0 / std::cos(4.0 * M_PI / 180.0), 0.1 * kMm);  // the wall past it
}

TEST(Rebin, FoldOverTakesTheNearestCrossingAndEmptyBinsStayInfinite) {
  SyntheticScan synthetic;
  synthetic.addLine(5.0, -20, 20, 10, 1.0f);  // early beams: a wall 5 m ahead
  synthetic.addLine(3.0, 0, 15, 200, 2.0f);   // late beams, folded over: a wall 3 m ahead
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(synthetic.scan, synthetic.grid, kInf, out);
  ASSERT_EQ(out.ranges.size(), 360u);
  for (int degrees = -180; degrees < 180; ++degrees) {
    const int bin = SyntheticScan::binOf(degrees);
    const double cosine = std::cos(degrees * M_PI / 180.0);
    if (degrees >= 0 && degrees <= 15) {
      EXPECT_NEAR(out.ranges[bin], 3.0 / cosine, 1e-5) << degrees;
      EXPECT_EQ(out.intensities[bin], 2.0f);
    } else if (degrees >= -20 && degrees <= 20) {
      EXPECT_NEAR(out.ranges[bin], 5.0 / cosine, 1e-5) << degrees;
      EXPECT_EQ(out.intensities[bin], 1.0f);
    } else {
      EXPECT_EQ(out.ranges[bin], kInf) << degrees;
    }
  }
}

TEST(Rebin, InterpolatesBetweenPointsOffTheGrid) {
  // Ten points at bearings 0.4, 1.4, ..., 9.4 deg on the line x = 4: bins 1..9 lie between points and
  // are interpolated on the line; bin 10 lies 0.6 deg past the last point and is not reached. Bin 0 lies
  // 0.4 deg before the first point: its ray meets the line 28 mm before it, and where the wall ends the
  // returns cannot tell, so that bin is left empty (a contour's end is followed at most 10 mm). With the
  // points at 0.1, 1.1, ... deg, bin 0's ray meets the line 7 mm before the first point: reached.
  for (const double offset_deg : {0.4, 0.1}) {
    SyntheticScan synthetic;
    for (int k = 0; k < 10; ++k) {
      const double bearing = (k + offset_deg) * M_PI / 180.0;
      synthetic.scan.points.push_back(
          {Eigen::Vector3d(4.0, 4.0 * std::tan(bearing), 0.0), 0.0, 0.0f, static_cast<std::uint32_t>(k)});
    }
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(synthetic.scan, synthetic.grid, 0.0f, out);
    EXPECT_TRUE(out.intensities.empty());
    for (int degrees = 1; degrees <= 9; ++degrees) {
      EXPECT_NEAR(out.ranges[SyntheticScan::binOf(degrees)], 4.0 / std::cos(degrees * M_PI / 180.0), 1e-5)
          << degrees;
    }
    if (offset_deg == 0.1)
      EXPECT_NEAR(out.ranges[SyntheticScan::binOf(0)], 4.0, 1e-5);
    else
      EXPECT_EQ(out.ranges[SyntheticScan::binOf(0)], 0.0f);  // the input's own "no return"
    EXPECT_EQ(out.ranges[SyntheticScan::binOf(-1)], 0.0f);
    EXPECT_EQ(out.ranges[SyntheticScan::binOf(10)], 0.0f);
  }
}

// Two returns 0.35 m apart on the two faces of a square pillar's corner (nearer than the gap at 20 m,
// neither on a line with a third): the chord between cuts the corner, up to 0.17 m off. Where the scan's
// noise is small, the surface between cannot be told from the returns: the bin between is left empty.
// A chord no longer than 20 mm (the surface between can then lie at most 10 mm off it) still fills.
TEST(Rebin, AChordWhoseSurfaceCannotBeToldIsLeftEmpty) {
  const double near_deg = 0.5, far_deg = 1.5;
  for (const double range : {20.0, 0.5}) {
    SyntheticScan synthetic;
    synthetic.addLine(2.0 * range, -10, -1, 0, 0.0f);  // a wall behind, up to the pillar
    const auto at = [&](double degrees, double r) {
      return Eigen::Vector3d(r * std::cos(degrees * M_PI / 180.0), r * std::sin(degrees * M_PI / 180.0), 0.0);
    };
    synthetic.scan.points.push_back({at(near_deg, range), 0.0, 0.0f, 10});
    synthetic.scan.points.push_back({at(far_deg, range * 1.002), 0.0, 0.0f, 11});
    ScanRebinner rebinner;
    RebinnedScan out;
    rebinner.rebin(synthetic.scan, synthetic.grid, 0.0f, out);
    const float between = out.ranges[SyntheticScan::binOf(1)];
    const double chord = (at(far_deg, range * 1.002) - at(near_deg, range)).norm();
    if (chord > 0.02)
      EXPECT_EQ(between, 0.0f) << range;
    else
      EXPECT_NEAR(between, range, 0.01) << range;
  }
}

TEST(Rebin, DepthJumpsAreNotBridged) {
  SyntheticScan synthetic;
  synthetic.addLine(2.0, -10, -1, 0, 0.0f);
  synthetic.addLine(6.0, 0, 10, 10, 0.0f);  // beam 9 -> 10 jumps 4 m: two contours
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(synthetic.scan, synthetic.grid, kInf, out);
  EXPECT_NEAR(out.ranges[SyntheticScan::binOf(-1)], 2.0 / std::cos(M_PI / 180.0), 1e-5);
  EXPECT_NEAR(out.ranges[SyntheticScan::binOf(0)], 6.0, 1e-5);
}

// noReturnValue() passes over blocks of beams at a time: the first range outside [range_min, range_max]
// (or NaN), wherever it lies in a scan of any length, of any kind; +inf when there is none.
TEST(Rebin, NoReturnValueIsTheFirstMissAtAnyPosition) {
  core::PlanarScan scan;
  scan.range_min = 0.1f;
  scan.range_max = 10.0f;
  const float kinds[] = {std::numeric_limits<float>::quiet_NaN(), kInf, -kInf, 0.0f, 0.09f, 10.5f};
  for (std::size_t n = 0; n <= 21; ++n) {
    for (std::size_t miss = 0; miss <= n; ++miss) {
      for (const float kind : kinds) {
        scan.ranges.assign(n, 0.0f);
        for (std::size_t i = 0; i < n; ++i)
          scan.ranges[i] = i % 2 == 0 ? 0.1f : 10.0f;  // the bounds are returns
        if (miss < n) {
          scan.ranges[miss] = kind;
          if (miss + 1 < n)
            scan.ranges[miss + 1] = 12.0f;  // a later miss is not the first
        }
        const float value = core::noReturnValue(scan);
        const float expected = miss < n ? kind : kInf;
        EXPECT_TRUE(std::isnan(expected) ? std::isnan(value) : value == expected)
            << n << " beams, miss at " << miss << ": " << value;
      }
    }
  }
}

TEST(Rebin, ClockwiseGridAndNoReturnValue) {
  core::PlanarScan scan;
  scan.range_min = 0.1f;
  scan.range_max = 10.0f;
  scan.ranges = {1.0f, 0.0f, 2.0f};
  EXPECT_EQ(core::noReturnValue(scan), 0.0f);
  scan.ranges = {1.0f, 2.0f};
  EXPECT_EQ(core::noReturnValue(scan), kInf);
  scan.ranges = {1.0f, 11.0f};
  EXPECT_EQ(core::noReturnValue(scan), 11.0f);

  // Clockwise grid from +10 deg down to -10 deg: the x = 3 line, bins in reverse order.
  SyntheticScan synthetic;
  synthetic.grid = {static_cast<float>(10 * M_PI / 180), static_cast<float>(-M_PI / 180), 21};
  for (int k = 0; k <= 20; ++k) {
    const double bearing = (10 - k) * M_PI / 180;
    synthetic.scan.points.push_back(
        {Eigen::Vector3d(3.0, 3.0 * std::tan(bearing), 0.0), 0.0, 0.0f, static_cast<std::uint32_t>(k)});
  }
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(synthetic.scan, synthetic.grid, kInf, out);
  for (int k = 0; k <= 20; ++k)
    EXPECT_NEAR(out.ranges[k], 3.0 / std::cos((10 - k) * M_PI / 180), 1e-5);
}

TEST(Rebin, NonFinitePointIsRejected) {
  SyntheticScan synthetic;
  synthetic.addLine(5.0, -2, 2, 0, 1.0f);
  synthetic.scan.points[2].position.y() = NAN;
  ScanRebinner rebinner;
  RebinnedScan out;
  try {
    rebinner.rebin(synthetic.scan, synthetic.grid, kInf, out);
    FAIL() << "expected InvalidInput";
  } catch (const core::InvalidInput& error) {
    EXPECT_EQ(error.field(), "points");
  }
}

// Bin positions come from a float bearing, confirmed in double near a ray (rebin.cpp, locatePoints()):
// points on a saw-tooth about the sensor (3.0 and 3.1 m in turn: all flat within the scan's tolerance),
// each on its beam's ray or beside it by 1e-12 to 1e-5 rad or a third of a bin, either way. Every bin's
// range is where its ray meets the segment between the two points around it (closed form); a point placed
// in a wrong bin would cross a ray with the wrong segment (micrometres off at 1e-6 rad) or miss it.
TEST(Rebin, PointsBesideTheirRaysAreCrossedByTheRightSegments) {
  struct Grid {
    double angle_min, increment;
    std::size_t count;
  };
  const Grid grids[] = {{-M_PI, 2.0 * M_PI / 360.0, 360}, {0.0, 2.0 * M_PI / 1440.0, 1440},
                        {M_PI, -M_PI / 180.0, 360},        {-2.35619449, 0.25 * M_PI / 180.0, 1081},
                        {100.0, M_PI / 180.0, 300},        {-0.3, -0.5 * M_PI / 180.0, 500}};
  const double offsets[] = {0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-7, -1e-7, 2e-6, -2e-6, 1e-5, -1e-5};
  ScanRebinner rebinner;
  for (const Grid& g : grids) {
    const core::AngleGrid grid{static_cast<float>(g.angle_min), static_cast<float>(g.increment), g.count};
    const double direction = g.increment > 0.0 ? 1.0 : -1.0;
    const auto rayAngle = [&](std::size_t b) {
      return static_cast<double>(grid.angle_min) + static_cast<double>(b) * grid.angle_increment;
    };
    std::vector<double> past(g.count);  // [rad] how far point i lies past its ray in the grid's direction
    DeskewedScan scan;
    for (std::size_t i = 0; i < g.count; ++i) {
      past[i] = i % 12 < 11 ? offsets[i % 12] : (i % 24 < 12 ? 1.0 : -1.0) * std::abs(g.increment) / 3.0;
      const double bearing = rayAngle(i) + direction * past[i], range = i % 2 ? 3.1 : 3.0;
      core::DeskewedPoint point{};
      point.position = Eigen::Vector3d(range * std::cos(bearing), range * std::sin(bearing), 0.0);
      point.beam_index = static_cast<std::uint32_t>(i);
      scan.points.push_back(point);
    }
    RebinnedScan out;
    rebinner.rebin(scan, grid, kInf, out);
    ASSERT_EQ(out.ranges.size(), g.count);
    for (std::size_t b = 0; b < g.count; ++b) {
      // The segment round ray b: from the point before it (in the grid's direction) to the one after.
      if ((b == 0 && past[b] > 0.0) || (b + 1 == g.count && past[b] < 0.0))
        continue;  // beyond the first or the last point (a full circle's last segment is not checked)
      const Eigen::Vector2d a = scan.points[past[b] > 0.0 ? b - 1 : b].position.head<2>();
      const Eigen::Vector2d c = scan.points[past[b] > 0.0 ? b : std::min(b + 1, g.count - 1)].position.head<2>();
      const Eigen::Vector2d ray(std::cos(rayAngle(b)), std::sin(rayAngle(b))), along = c - a;
      const double expected = past[b] == 0.0 ? a.norm()  // on its ray
                                             : (a.x() * along.y() - a.y() * along.x()) /
                                                   (ray.x() * along.y() - ray.y() * along.x());
      EXPECT_NEAR(out.ranges[b], expected, 1e-3 * kMm)
          << "grid " << g.angle_min << " " << g.increment << " x " << g.count << ", bin " << b;
    }
  }
}

TEST(Rebin, ConfigValidationNamesTheParameter) {
  core::RebinConfig config;
  config.min_gap = -1.0;
  try {
    ScanRebinner rebinner(config);
    FAIL();
  } catch (const core::InvalidInput& error) {
    EXPECT_EQ(error.field(), "rebin_min_gap");
  }
}

}  // namespace
}  // namespace lidar_deskew
