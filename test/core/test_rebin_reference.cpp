// Old against new (issue 35): core::ScanRebinner against the re-binner it replaced (frozen in
// test/support/reference_rebin.*), judged by the scan metrics deskew_metrics prints (src/eval/evaluate.cpp):
// the share of filled bins farther than 10 mm from every true wall, the bins the truth-corrected scan fills
// that are left empty, and the 95th percentile of the bins' distance from the walls. Every corrected scan
// of a planar scenario of the simulator, counter-clockwise and clockwise, range noise off and on; the
// truth-corrected scan is the old re-binner's on the true points, one reference for both.
//
// The whole planar suite's table (about a minute):
//   test_rebin_reference --gtest_also_run_disabled_tests --gtest_filter='*WholePlanarSuite*'
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/sim/scenario.h"
#include "lidar_deskew/sim/sim.h"
#include "support/reference_rebin.h"
#include "support/truth.h"

namespace lidar_deskew {
namespace {

using test::kEpoch;

/// The scan metrics of re-binned scans against the true walls and the truth-corrected scans.
struct BinMetrics {
  std::size_t filled = 0;        // bins with a return
  std::size_t over_1cm = 0;      // of those, farther than 10 mm from every true wall
  std::size_t truth_filled = 0;  // bins the truth-corrected scan fills
  std::size_t emptied = 0;       // of those, left empty
  std::vector<double> errors;    // [m] every filled bin's distance from the walls

  void add(const core::RebinnedScan& scan, const core::RebinnedScan& truth, const sim::World& world,
           const sim::Pose2& laser, const core::AngleGrid& grid) {
    for (std::size_t b = 0; b < scan.ranges.size(); ++b) {
      const bool ours = std::isfinite(scan.ranges[b]);
      if (std::isfinite(truth.ranges[b])) {
        ++truth_filled;
        emptied += !ours;
      }
      if (!ours)
        continue;
      ++filled;
      const double angle = grid.angle_min + static_cast<double>(b) * grid.angle_increment;
      const Eigen::Vector2d endpoint =
          laser.apply(scan.ranges[b] * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
      errors.push_back(world.distanceTo(endpoint));
      over_1cm += errors.back() > 0.01;
    }
  }
  // The figures as printed (and compared: within their rounding).
  double overPercent() const { return filled ? 100.0 * static_cast<double>(over_1cm) / filled : 0.0; }
  double emptiedPercent() const {
    return truth_filled ? 100.0 * static_cast<double>(emptied) / truth_filled : 0.0;
  }
  double p95Mm() const { return 1e3 * sim::errorStats(errors).p95; }
};

/// Old and new on one scenario (one direction, noise off or on).
struct Comparison {
  std::string name;
  BinMetrics old_metrics, new_metrics;
  std::size_t scans = 0;
};

Comparison compare(const sim::Scenario& scenario, bool noise, unsigned seed) {
  Comparison comparison;
  comparison.name = scenario.name + (noise ? " noise" : "");
  const sim::PiecewiseTrajectory trajectory = scenario.trajectory();
  std::mt19937 rng(seed);
  core::ScanDeskewer deskewer;
  core::ScanRebinner rebinner;  // one per stream, as the node keeps it
  test::ReferenceRebinner reference, truth_rebinner;
  core::RebinnedScan got, expected, truth_scan;
  for (int k = 0; k / scenario.lidar.rate < scenario.duration; ++k) {
    const double start = k / scenario.lidar.rate;
    sim::SimulatedScan simulated = sim::simulateScan(scenario.world, trajectory, scenario.mount,
                                                     scenario.lidar, kEpoch, start, noise ? &rng : nullptr);
    if (k % 2 == 1) {  // every other scan carries intensities (interpolated along the contour)
      simulated.scan.intensities.resize(simulated.scan.ranges.size());
      for (std::size_t i = 0; i < simulated.scan.ranges.size(); ++i)
        simulated.scan.intensities[i] = static_cast<float>(100 + (i * 37) % 1000);
    }
    // Poses as tf gives them: samples at 50 Hz, linear between (so the correction keeps some error).
    const core::PoseSamples samples = test::sampleTrajectory(
        trajectory, kEpoch, std::max(0.0, start - 0.1), start + scenario.lidar.sweepDuration() + 0.1, 0.02);
    core::DeskewedScan corrected;
    deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), test::toMrpt(scenario.mount),
                    samples, corrected);
    const core::AngleGrid grid{simulated.scan.angle_min, simulated.scan.angle_increment,
                               simulated.scan.ranges.size()};
    const float no_return = core::noReturnValue(simulated.scan);
    rebinner.rebin(corrected, grid, no_return, got);
    reference.rebin(corrected, grid, no_return, expected);
    core::DeskewedScan truth = corrected;
    const auto true_points =
        test::truePointsAtReference(simulated, corrected, trajectory, scenario.mount, kEpoch);
    for (std::size_t j = 0; j < truth.points.size(); ++j)
      truth.points[j].position.head<2>() = true_points[j];
    truth_rebinner.rebin(truth, grid, no_return, truth_scan);
    const sim::Pose2 laser =
        trajectory.pose(core::nsToSeconds(corrected.reference_time - kEpoch)).compose(scenario.mount);
    comparison.old_metrics.add(expected, truth_scan, scenario.world, laser, grid);
    comparison.new_metrics.add(got, truth_scan, scenario.world, laser, grid);
    ++comparison.scans;
  }
  return comparison;
}

void printHeader() {
  std::printf("%-50s %5s | %-28s | %-28s\n", "scenario", "scans", "old: >10mm %  emptied %  p95",
              "new: >10mm %  emptied %  p95");
}

void printRow(const Comparison& c) {
  const BinMetrics &o = c.old_metrics, &n = c.new_metrics;
  std::printf("%-50s %5zu | %10.2f %9.2f %6.2f | %10.2f %9.2f %6.2f\n", c.name.c_str(), c.scans,
              o.overPercent(), o.emptiedPercent(), o.p95Mm(), n.overPercent(), n.emptiedPercent(), n.p95Mm());
}

/// The new re-binner no worse than the old by any figure as printed (2 decimals: within 0.005).
void expectNeverWorse(const Comparison& c) {
  const BinMetrics &o = c.old_metrics, &n = c.new_metrics;
  EXPECT_LE(n.overPercent(), o.overPercent() + 0.005) << c.name;
  EXPECT_LE(n.emptiedPercent(), o.emptiedPercent() + 0.005) << c.name;
  EXPECT_LE(n.p95Mm(), o.p95Mm() + 0.005) << c.name;
}

/// Every planar scenario (optionally only those named), both directions, noise off and on.
void compareScenarios(const std::vector<std::string>& only) {
  printHeader();
  unsigned seed = 1;
  for (const bool clockwise : {false, true}) {
    for (const sim::Scenario& base : sim::planarScenarios()) {
      if (!only.empty() && std::find(only.begin(), only.end(), base.name) == only.end())
        continue;
      const sim::Scenario scenario = clockwise ? sim::clockwiseVariant(base) : base;
      for (const bool noise : {false, true}) {
        const Comparison comparison = compare(scenario, noise, seed++);
        printRow(comparison);
        expectNeverWorse(comparison);
      }
    }
  }
}

// A few scenarios within seconds: the three paper sensors at high speed (folds, 1440 and 1080 beams),
// the LDS-01 in its small room (corners, depth steps), the varying drive.
TEST(RebinReference, NeverWorseThanTheOldRebinnerOnAFewScenarios) {
  compareScenarios({"UTM-30LX/high/arc", "ILD26TRI/high/rotation", "UTM-30LX-270/normal/translation",
                    "LDS-01/high/arc", "LDS-01/normal/translation", "ILD26TRI/varying/varying"});
}

TEST(RebinReference, DISABLED_WholePlanarSuite) {
  compareScenarios({});
}

// Grids and motions the scenarios lack: grids wider than a turn (361 and 370 x 1 deg), a narrow one, spins
// fast enough to fold the scan over itself (either way), dropouts (lone returns, contour ends), noise.
TEST(RebinReference, NeverWorseOnOddGridsFoldOversAndDropouts) {
  std::vector<sim::LidarModel> models = {sim::LidarModel::ild26tri(), sim::LidarModel::utm30lx360(),
                                         sim::LidarModel::utm30lx270(), sim::LidarModel::lds01()};
  sim::LidarModel wide = sim::LidarModel::ild26tri();
  wide.beams = 361;
  wide.field_of_view = 361.0 * M_PI / 180.0;
  models.push_back(wide);
  wide.beams = 370;  // first and last ten beams on the same rays
  wide.field_of_view = 370.0 * M_PI / 180.0;
  models.push_back(wide);
  sim::LidarModel narrow = sim::LidarModel::utm30lx270();
  narrow.beams = 100;
  narrow.field_of_view = 0.5 * M_PI;
  models.push_back(narrow);
  BinMetrics old_total, new_total;
  std::mt19937 rng(7);
  const sim::World world = sim::World::demoRoom();
  for (const sim::LidarModel& base_model : models) {
    for (const bool clockwise : {false, true}) {
      sim::LidarModel model = base_model;
      model.clockwise = clockwise;
      for (const double turn_rate : {0.0, 5.0, -20.0, 70.0, -70.0}) {
        for (const bool noise : {false, true}) {
          const sim::ArcTrajectory motion({1.0, -0.5, 0.7}, 1.5, turn_rate);
          const sim::Pose2 mount{0.25, 0.05, 0.1};
          sim::SimulatedScan simulated =
              sim::simulateScan(world, motion, mount, model, kEpoch, 0.0, noise ? &rng : nullptr);
          simulated.scan.intensities.assign(simulated.scan.ranges.size(), 0.0f);
          for (std::size_t i = 0; i < simulated.scan.ranges.size(); ++i) {
            simulated.scan.intensities[i] = static_cast<float>(i % 97);
            if (i % 23 == 5 || (i % 41 >= 7 && i % 41 <= 9))
              simulated.scan.ranges[i] = 0.0f;  // dropouts
          }
          const core::PoseSamples samples =
              test::sampleTrajectory(motion, kEpoch, 0.0, simulated.beam_times.back() + 0.01, 0.0005);
          core::ScanDeskewer deskewer;
          core::DeskewedScan corrected;
          deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}), test::toMrpt(mount),
                          samples, corrected);
          const core::AngleGrid grid{simulated.scan.angle_min, simulated.scan.angle_increment,
                                     simulated.scan.ranges.size()};
          const float no_return = core::noReturnValue(simulated.scan);
          core::ScanRebinner rebinner;
          test::ReferenceRebinner reference;
          core::RebinnedScan got, expected, truth_scan;
          rebinner.rebin(corrected, grid, no_return, got);
          reference.rebin(corrected, grid, no_return, expected);
          ASSERT_EQ(got.ranges.size(), grid.count);
          ASSERT_EQ(got.intensities.size(), grid.count);
          core::DeskewedScan truth = corrected;
          const auto true_points = test::truePointsAtReference(simulated, corrected, motion, mount, kEpoch);
          for (std::size_t j = 0; j < truth.points.size(); ++j)
            truth.points[j].position.head<2>() = true_points[j];
          reference.rebin(truth, grid, no_return, truth_scan);
          for (std::size_t b = 0; b < grid.count; ++b) {  // no return is the input's own value (0)
            got.ranges[b] = got.ranges[b] == no_return ? INFINITY : got.ranges[b];
            expected.ranges[b] = expected.ranges[b] == no_return ? INFINITY : expected.ranges[b];
            truth_scan.ranges[b] = truth_scan.ranges[b] == no_return ? INFINITY : truth_scan.ranges[b];
          }
          const sim::Pose2 laser =
              motion.pose(core::nsToSeconds(corrected.reference_time - kEpoch)).compose(mount);
          BinMetrics old_metrics, new_metrics;
          old_metrics.add(expected, truth_scan, world, laser, grid);
          new_metrics.add(got, truth_scan, world, laser, grid);
          if (new_metrics.over_1cm > old_metrics.over_1cm || new_metrics.emptied > old_metrics.emptied) {
            std::printf(
                "%d beams, clockwise %d, %.0f rad/s, noise %d: > 10 mm old %zu new %zu, emptied old %zu "
                "new %zu\n",
                model.beams, clockwise, turn_rate, noise, old_metrics.over_1cm, new_metrics.over_1cm,
                old_metrics.emptied, new_metrics.emptied);
          }
          old_total.over_1cm += old_metrics.over_1cm;
          old_total.emptied += old_metrics.emptied;
          new_total.over_1cm += new_metrics.over_1cm;
          new_total.emptied += new_metrics.emptied;
        }
      }
    }
  }
  std::printf("odd grids: > 10 mm old %zu new %zu, emptied old %zu new %zu\n", old_total.over_1cm,
              new_total.over_1cm, old_total.emptied, new_total.emptied);
  EXPECT_LE(new_total.over_1cm, old_total.over_1cm);
  EXPECT_LE(new_total.emptied, old_total.emptied);
}

}  // namespace
}  // namespace lidar_deskew
