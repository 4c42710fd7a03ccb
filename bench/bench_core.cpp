// Per-scan cost of the ROS-free core (Google Benchmark). Prints Google Benchmark's table, then a
// summary in ns per point. Run: bench/run.sh core (pins to one core).
//
// Scans are simulated on a 6 m/s, 5 rad/s arc with the laser off the rotation centre; poses come as
// samples at 50 Hz (what odom -> base_link on tf gives), knots every 5 ms (the default).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <random>
#include <string>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"
#include "lidar_deskew/sim/sim.h"
#include "summary_run.h"
#include "support/reference_rebin.h"

namespace {

using namespace lidar_deskew;

constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;

mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose) {
  return mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0);
}

sim::LidarModel modelWithBeams(int beams) {
  switch (beams) {
    case 360:
      return sim::LidarModel::ild26tri();
    case 1080:
      return sim::LidarModel::utm30lx270();
    default:
      return sim::LidarModel::utm30lx360();
  }
}

struct Fixture {
  explicit Fixture(int beams) : trajectory({-2.0, -1.0, 0.3}, 6.0, 5.0) {
    simulated =
        sim::simulateScan(sim::World::demoRoom(), trajectory, mount, modelWithBeams(beams), kEpoch, 0.0);
    timing = core::resolveTiming(simulated.scan, {});
    for (double t = -0.1; t < 0.5; t += 0.02)
      poses.add(kEpoch + core::secondsToNs(t), toMrpt(trajectory.pose(t)));
  }
  sim::ArcTrajectory trajectory;
  sim::Pose2 mount{0.25, 0.05, 0.1};
  sim::SimulatedScan simulated;
  core::BeamTiming timing;
  core::PoseSamples poses;
};

void setPerPoint(benchmark::State& state, std::size_t points) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * points));
  state.counters["points"] = static_cast<double>(points);
}

void BM_DeskewScan(benchmark::State& state) {
  Fixture fixture(static_cast<int>(state.range(0)));
  core::DeskewConfig config;
  config.knot_interval = state.range(1) ? 0.005 : 0.0;
  core::ScanDeskewer deskewer(config);
  core::DeskewedScan out;
  const auto mount = toMrpt(fixture.mount);
  for (auto _ : state) {
    deskewer.deskew(fixture.simulated.scan, fixture.timing, mount, fixture.poses, out);
    benchmark::DoNotOptimize(out.points.data());
  }
  setPerPoint(state, fixture.simulated.scan.ranges.size());
}
BENCHMARK(BM_DeskewScan)
    ->ArgNames({"beams", "knots"})
    ->Args({360, 1})
    ->Args({1080, 1})
    ->Args({1440, 1})
    ->Args({1440, 0});

/// Re-binning one corrected scan with `Rebinner` (core::ScanRebinner, or the one issue 35 replaced).
template <typename Rebinner>
void rebinScan(benchmark::State& state) {
  Fixture fixture(static_cast<int>(state.range(0)));
  core::ScanDeskewer deskewer;
  core::DeskewedScan corrected;
  deskewer.deskew(fixture.simulated.scan, fixture.timing, toMrpt(fixture.mount), fixture.poses, corrected);
  const core::AngleGrid grid{fixture.simulated.scan.angle_min, fixture.simulated.scan.angle_increment,
                             fixture.simulated.scan.ranges.size()};
  Rebinner rebinner;
  core::RebinnedScan out;
  for (auto _ : state) {
    rebinner.rebin(corrected, grid, core::noReturnValue(fixture.simulated.scan), out);
    benchmark::DoNotOptimize(out.ranges.data());
  }
  setPerPoint(state, fixture.simulated.scan.ranges.size());
}
void BM_Rebin(benchmark::State& state) {
  rebinScan<core::ScanRebinner>(state);
}
BENCHMARK(BM_Rebin)->ArgNames({"beams"})->Arg(360)->Arg(1080)->Arg(1440);
/// The re-binner before issue 35 (test/support/reference_rebin.h), for the comparison in one run.
void BM_RebinReference(benchmark::State& state) {
  rebinScan<test::ReferenceRebinner>(state);
}
BENCHMARK(BM_RebinReference)->ArgNames({"beams"})->Arg(360)->Arg(1080)->Arg(1440);

// A 3D-style cloud: 128 rings x 1024 columns at 10 Hz, each column 1/10240 s after the previous.
void BM_DeskewPointsPerPointTimes(benchmark::State& state) {
  const sim::ArcTrajectory trajectory({0.0, 0.0, 0.0}, 6.0, 5.0);
  core::PoseSamples poses;
  for (double t = -0.1; t < 0.5; t += 0.02)
    poses.add(kEpoch + core::secondsToNs(t), toMrpt(trajectory.pose(t)));
  const int rings = 128, columns = 1024;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> offsets;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> range(1.0, 40.0);
  for (int column = 0; column < columns; ++column) {
    const double azimuth = 2.0 * M_PI * column / columns;
    for (int ring = 0; ring < rings; ++ring) {
      const double elevation = (-22.5 + 45.0 * ring / (rings - 1)) * M_PI / 180.0;
      const double r = range(rng);
      points.emplace_back(r * std::cos(elevation) * std::cos(azimuth),
                          r * std::cos(elevation) * std::sin(azimuth), r * std::sin(elevation));
      offsets.push_back(0.1 * column / columns);
    }
  }
  core::ScanDeskewer deskewer;
  std::vector<Eigen::Vector3d> corrected;
  std::vector<double> corrected_offsets;
  std::vector<std::uint32_t> kept;
  const auto mount = mrpt::poses::CPose3D::FromXYZYawPitchRoll(0.25, 0.05, 0.4, 0.1, 0.0, 0.0);
  for (auto _ : state) {
    deskewer.deskewPoints(points, offsets, kEpoch, mount, poses, corrected, corrected_offsets, kept);
    benchmark::DoNotOptimize(corrected.data());
  }
  setPerPoint(state, points.size());
}
BENCHMARK(BM_DeskewPointsPerPointTimes)->Unit(benchmark::kMicrosecond);

/// Google Benchmark's console table, then one line per benchmark: ns per point and per scan.
class SummaryReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (!bench::isSummaryRun(run))  // one line per benchmark
        continue;
      const double points = run.counters.at("points").value;
      const double ns_per_call =
          run.GetAdjustedRealTime() * (run.time_unit == benchmark::kMicrosecond ? 1e3 : 1.0);
      summary_.emplace_back(run.run_name.str(), ns_per_call, points);
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\n%-52s %12s %10s %12s\n", "benchmark", "points", "ns/point", "us/scan");
    for (const auto& [name, ns_per_call, points] : summary_) {
      std::printf("%-52s %12.0f %10.2f %12.2f\n", name.c_str(), points, ns_per_call / points,
                  ns_per_call * 1e-3);
    }
  }

 private:
  std::vector<std::tuple<std::string, double, double>> summary_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv))
    return 1;
  SummaryReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
