// Per-point cost of correcting a multi-line cloud (Google Benchmark): an OS1-64 sweep (64 x 1024 =
// 65,536 points, organized, Ouster's layout) on a 6 m/s arc, tf at 50 Hz through a real TfFeed.
// - BM_CloudCore: the core alone (ScanDeskewer::deskewFirings on the prepared returns and firings);
// - BM_CloudCorePerPointTimes: the same points through deskewPoints (a time per point: read row by row,
//   no two consecutive points share one, so each gets its own map);
// - BM_CloudNodeletPath: what the nodelet and deskew_bag do per cloud: parse (layout, time field, every
//   point's time), correct, build the output message; BM_CloudPrepare and BM_CloudCorrectAndBuild its
//   two halves.
// Prints Google Benchmark's table with ns_per_point. Run: bench/run.sh cloud (pins to one core).
#include <benchmark/benchmark.h>

#include <cstdlib>

#include "lidar_deskew/ros/cloud_processor.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/tf_feed.h"
#include "lidar_deskew/sim/cloud_bag.h"
#include "lidar_deskew/sim/cloud_scenario.h"

namespace {

using namespace lidar_deskew;

constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;

struct Fixture {
  Fixture() : feed("odom", "base_link", 10.0, [](ros_adapter::TfEvent, const std::string&) {}) {
    const sim::CloudScenario scenario = sim::findCloudScenario("OS1-64/high/arc");
    const auto trajectory = scenario.trajectory();
    const sim::SimulatedCloud sweep =
        sim::simulateSweep(sim::World3::hall(), *trajectory, scenario.mount, scenario.lidar, 0.0);
    cloud = boost::make_shared<sensor_msgs::PointCloud2>(
        sim::toPointCloud2(sweep, sim::CloudConvention::kOuster, kEpoch, "lidar"));
    feed.add(sim::stamped("base_link", "lidar", kEpoch, scenario.mount), true);
    for (double t = -0.1; t < 0.3; t += 0.02)
      feed.add(sim::stamped("odom", "base_link", kEpoch + core::secondsToNs(t), trajectory->pose(t)), false);
    std::string error;
    mount = *feed.mount("lidar", error);
    points = static_cast<double>(cloud->width) * cloud->height;
  }
  ros_adapter::TfFeed feed;
  sensor_msgs::PointCloud2::Ptr cloud;
  mrpt::poses::CPose3D mount;
  double points = 0.0;
};

// A fixed iteration count (callgrind: instructions per cloud over exactly so many), else Google
// Benchmark's own.
void fixedIterations(benchmark::internal::Benchmark* benchmark) {
  if (const char* const fixed = std::getenv("LIDAR_DESKEW_BENCH_ITERATIONS"))
    benchmark->Iterations(std::atoll(fixed));
}

Fixture& fixture() {
  static Fixture instance;
  return instance;
}

void BM_CloudCore(benchmark::State& state) {
  Fixture& f = fixture();
  ros_adapter::CloudProcessor processor{ros_adapter::DeskewParams()};
  const ros_adapter::PreparedCloud prepared = processor.prepare(f.cloud);
  core::ScanDeskewer deskewer;
  std::vector<Eigen::Vector3d> corrected;
  for (auto _ : state) {
    deskewer.deskewFirings(prepared.points, prepared.firings, prepared.first, f.mount, f.feed.motion(),
                           corrected);
    benchmark::DoNotOptimize(corrected.data());
  }
  state.counters["points"] = f.points;
  state.counters["ns_per_point"] = benchmark::Counter(
      f.points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CloudCore)->Unit(benchmark::kMillisecond)->Apply(fixedIterations);

// The same points through the per-point-times entry (deskewPoints: every point with its own offset,
// runs of one time found by the core).
void BM_CloudCorePerPointTimes(benchmark::State& state) {
  Fixture& f = fixture();
  ros_adapter::CloudProcessor processor{ros_adapter::DeskewParams()};
  const ros_adapter::PreparedCloud prepared = processor.prepare(f.cloud);
  std::vector<double> offsets(prepared.points.size());
  for (std::size_t i = 0; i < offsets.size(); ++i)
    offsets[i] = core::nsToSeconds(prepared.timeOf(i) - prepared.first);
  core::ScanDeskewer deskewer;
  std::vector<Eigen::Vector3d> corrected;
  std::vector<double> corrected_offsets;
  std::vector<std::uint32_t> kept;
  for (auto _ : state) {
    deskewer.deskewPoints(prepared.points, offsets, prepared.first, f.mount, f.feed.motion(), corrected,
                          corrected_offsets, kept);
    benchmark::DoNotOptimize(corrected.data());
  }
  state.counters["points"] = f.points;
  state.counters["ns_per_point"] = benchmark::Counter(
      f.points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CloudCorePerPointTimes)->Unit(benchmark::kMillisecond)->Apply(fixedIterations);

void BM_CloudNodeletPath(benchmark::State& state) {
  Fixture& f = fixture();
  ros_adapter::CloudProcessor processor{ros_adapter::DeskewParams()};
  for (auto _ : state) {
    const ros_adapter::PreparedCloud prepared = processor.prepare(f.cloud);
    const ros_adapter::CloudOutputs outputs = processor.correct(prepared, f.mount, f.feed.motion());
    benchmark::DoNotOptimize(outputs.cloud.get());
  }
  state.counters["points"] = f.points;
  state.counters["ns_per_point"] = benchmark::Counter(
      f.points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CloudNodeletPath)->Unit(benchmark::kMillisecond)->Apply(fixedIterations);

// Its two halves: parse (layout, returns, time field, firings) ...
void BM_CloudPrepare(benchmark::State& state) {
  Fixture& f = fixture();
  ros_adapter::CloudProcessor processor{ros_adapter::DeskewParams()};
  for (auto _ : state) {
    const ros_adapter::PreparedCloud prepared = processor.prepare(f.cloud);
    benchmark::DoNotOptimize(prepared.points.data());
  }
  state.counters["ns_per_point"] = benchmark::Counter(
      f.points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CloudPrepare)->Unit(benchmark::kMillisecond)->Apply(fixedIterations);

// ... and correct (the core) and build the output message.
void BM_CloudCorrectAndBuild(benchmark::State& state) {
  Fixture& f = fixture();
  ros_adapter::CloudProcessor processor{ros_adapter::DeskewParams()};
  const ros_adapter::PreparedCloud prepared = processor.prepare(f.cloud);
  for (auto _ : state) {
    const ros_adapter::CloudOutputs outputs = processor.correct(prepared, f.mount, f.feed.motion());
    benchmark::DoNotOptimize(outputs.cloud.get());
  }
  state.counters["ns_per_point"] = benchmark::Counter(
      f.points, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_CloudCorrectAndBuild)->Unit(benchmark::kMillisecond)->Apply(fixedIterations);

}  // namespace

BENCHMARK_MAIN();
