// Old against new (issue 25): core::ScanRebinner against the re-binner it replaced (frozen in
// test/support/reference_rebin.*), on every corrected scan of every planar scenario of the simulator,
// counter-clockwise and clockwise, range noise off and on. Where the two differ, the new one must be no
// worse by the scan metrics of issue 24 (bins > 10 mm from every true wall; bins the truth-corrected scan
// fills that are left empty).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/sim/scenario.h"
#include "support/reference_rebin.h"
#include "support/truth.h"

namespace lidar_deskew {
namespace {

using test::kEpoch;

/// The scan metrics of one re-binned scan against the true walls and the truth-corrected scan.
struct BinMetrics {
  std::size_t filled = 0;    // bins with a return
  std::size_t over_1cm = 0;  // of those, farther than 10 mm from every true wall
  std::size_t emptied = 0;   // bins the truth-corrected scan fills and this one leaves empty
  void add(const BinMetrics& other) {
    filled += other.filled;
    over_1cm += other.over_1cm;
    emptied += other.emptied;
  }
};

BinMetrics metricsOf(const core::RebinnedScan& scan, const core::RebinnedScan& truth, const sim::World& world,
                     const sim::Pose2& laser, const core::AngleGrid& grid) {
  BinMetrics metrics;
  for (std::size_t b = 0; b < scan.ranges.size(); ++b) {
    const bool ours = std::isfinite(scan.ranges[b]);
    metrics.emptied += std::isfinite(truth.ranges[b]) && !ours;
    if (!ours)
      continue;
    ++metrics.filled;
    const double angle = grid.angle_min + static_cast<double>(b) * grid.angle_increment;
    const Eigen::Vector2d endpoint =
        laser.apply(scan.ranges[b] * Eigen::Vector2d(std::cos(angle), std::sin(angle)));
    metrics.over_1cm += world.distanceTo(endpoint) > 0.01;
  }
  return metrics;
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

TEST(RebinReference, BitIdenticalToTheOldRebinnerOnEveryPlanarScenario) {
  std::size_t scans = 0, identical = 0, bins = 0;
  BinMetrics old_total, new_total;
  for (const bool clockwise : {false, true}) {
    for (const sim::Scenario& base : sim::planarScenarios()) {
      const sim::Scenario scenario = clockwise ? sim::clockwiseVariant(base) : base;
      for (const bool noise : {false, true}) {
        const sim::PiecewiseTrajectory trajectory = scenario.trajectory();
        std::mt19937 rng(static_cast<unsigned>(scans + 1));
        core::ScanDeskewer deskewer;
        core::ScanRebinner rebinner;  // one per stream, as the node keeps it
        test::ReferenceRebinner reference, truth_rebinner;
        core::RebinnedScan got, expected, truth_scan;
        std::size_t scenario_scans = 0, scenario_identical = 0;
        for (int k = 0; k / scenario.lidar.rate < scenario.duration; ++k) {
          const double start = k / scenario.lidar.rate;
          sim::SimulatedScan simulated =
              sim::simulateScan(scenario.world, trajectory, scenario.mount, scenario.lidar, kEpoch, start,
                                noise ? &rng : nullptr);
          if (k % 2 == 1) {  // every other scan carries intensities (interpolated along the contour)
            simulated.scan.intensities.resize(simulated.scan.ranges.size());
            for (std::size_t i = 0; i < simulated.scan.ranges.size(); ++i)
              simulated.scan.intensities[i] = static_cast<float>(100 + (i * 37) % 1000);
          }
          // Poses as tf gives them: samples at 50 Hz, linear between (so the correction keeps some error).
          const core::PoseSamples samples =
              test::sampleTrajectory(trajectory, kEpoch, std::max(0.0, start - 0.1),
                                     start + scenario.lidar.sweepDuration() + 0.1, 0.02);
          core::DeskewedScan corrected;
          deskewer.deskew(simulated.scan, core::resolveTiming(simulated.scan, {}),
                          test::toMrpt(scenario.mount), samples, corrected);
          const core::AngleGrid grid{simulated.scan.angle_min, simulated.scan.angle_increment,
                                     simulated.scan.ranges.size()};
          const float no_return = core::noReturnValue(simulated.scan);
          rebinner.rebin(corrected, grid, no_return, got);
          reference.rebin(corrected, grid, no_return, expected);
          ++scans;
          ++scenario_scans;
          bins += grid.count;
          if (sameBits(got.ranges, expected.ranges) && sameBits(got.intensities, expected.intensities)) {
            ++identical;
            ++scenario_identical;
            continue;
          }
          // Not identical: score both against the truth.
          core::DeskewedScan truth = corrected;
          const auto true_points =
              test::truePointsAtReference(simulated, corrected, trajectory, scenario.mount, kEpoch);
          for (std::size_t j = 0; j < truth.points.size(); ++j)
            truth.points[j].position.head<2>() = true_points[j];
          truth_rebinner.rebin(truth, grid, no_return, truth_scan);
          const sim::Pose2 laser =
              trajectory.pose(core::nsToSeconds(corrected.reference_time - kEpoch)).compose(scenario.mount);
          old_total.add(metricsOf(expected, truth_scan, scenario.world, laser, grid));
          new_total.add(metricsOf(got, truth_scan, scenario.world, laser, grid));
        }
        if (scenario_identical != scenario_scans) {
          std::printf("%-36s noise %-3s: %zu of %zu scans not bit-identical\n", scenario.name.c_str(),
                      noise ? "on" : "off", scenario_scans - scenario_identical, scenario_scans);
        }
      }
    }
  }
  std::printf("%zu scans (%zu bins): %zu bit-identical\n", scans, bins, identical);
  std::printf("where not: old %zu of %zu bins > 10 mm off, %zu emptied; new %zu of %zu, %zu emptied\n",
              old_total.over_1cm, old_total.filled, old_total.emptied, new_total.over_1cm, new_total.filled,
              new_total.emptied);
  EXPECT_GT(scans, 1000u);
  EXPECT_LE(new_total.over_1cm, old_total.over_1cm);
  EXPECT_LE(new_total.emptied, old_total.emptied);
}

// Grids and motions the scenarios lack: grids wider than a turn (361 and 370 x 1 deg), a narrow one, spins
// fast enough to fold the scan over itself (either way), dropouts (lone returns, contour ends), noise.
TEST(RebinReference, BitIdenticalOnOddGridsFoldOversAndDropouts) {
  std::vector<sim::LidarModel> models = {sim::LidarModel::ild26tri(), sim::LidarModel::utm30lx360(),
                                         sim::LidarModel::utm30lx270(), sim::LidarModel::lds01()};
  sim::LidarModel wide = sim::LidarModel::ild26tri();
  wide.beams = 361;
  wide.field_of_view = 361.0 * M_PI / 180.0;
  models.push_back(wide);
  wide.beams = 370;  // first and last ten beams on the same rays: swept by bearing, not by running positions
  wide.field_of_view = 370.0 * M_PI / 180.0;
  models.push_back(wide);
  sim::LidarModel narrow = sim::LidarModel::utm30lx270();
  narrow.beams = 100;
  narrow.field_of_view = 0.5 * M_PI;
  models.push_back(narrow);
  std::size_t scans = 0, identical = 0;
  std::mt19937 rng(7);
  for (const sim::LidarModel& base_model : models) {
    for (const bool clockwise : {false, true}) {
      sim::LidarModel model = base_model;
      model.clockwise = clockwise;
      for (const double turn_rate : {0.0, 5.0, -20.0, 70.0, -70.0}) {
        for (const bool noise : {false, true}) {
          const sim::ArcTrajectory motion({1.0, -0.5, 0.7}, 1.5, turn_rate);
          const sim::Pose2 mount{0.25, 0.05, 0.1};
          sim::SimulatedScan simulated = sim::simulateScan(sim::World::demoRoom(), motion, mount, model,
                                                           kEpoch, 0.0, noise ? &rng : nullptr);
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
          core::ScanRebinner rebinner;
          test::ReferenceRebinner reference;
          core::RebinnedScan got, expected;
          rebinner.rebin(corrected, grid, core::noReturnValue(simulated.scan), got);
          reference.rebin(corrected, grid, core::noReturnValue(simulated.scan), expected);
          ++scans;
          const bool same =
              sameBits(got.ranges, expected.ranges) && sameBits(got.intensities, expected.intensities);
          identical += same;
          EXPECT_TRUE(same) << model.beams << " beams, clockwise " << clockwise << ", " << turn_rate
                            << " rad/s, noise " << noise;
        }
      }
    }
  }
  std::printf("%zu scans: %zu bit-identical\n", scans, identical);
}

}  // namespace
}  // namespace lidar_deskew
