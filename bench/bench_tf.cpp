// Per-scan cost with tf lookups included, and accuracy against truth: our knots (default: twist
// interpolation; and linear, tf2's), our exact per-beam lookups, and laser_geometry's fixed-frame
// transformLaserScanToPointCloud, on the same scans and the same tf2 buffer. Run: bench/run.sh tf (pins to
// one core).
//
// scan_path/<sensor> is the whole per-scan path of the node and deskew_bag (ScanProcessor: the message
// checked and timed, the mount looked up, corrected, re-binned, both output messages built); bench/run.sh
// scan runs it next to laser_geometry and prints their ratio.
//
// The simulator drives a 6 m/s, 5 rad/s arc through a 12 x 8 m room, the laser 0.25 m ahead of the
// base; tf holds odom -> base_link at 50 Hz (the true pose) and the static mount.
#include <benchmark/benchmark.h>
#include <laser_geometry/laser_geometry.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2/buffer_core.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <string>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"
#include "lidar_deskew/ros/tf_feed.h"
#include "lidar_deskew/sim/sim.h"
#include "summary_run.h"

namespace {

using namespace lidar_deskew;

constexpr core::TimeNs kEpoch = 1'700'000'000'000'000'000;

sim::LidarModel lds01() {  // an LDS-01-like 5 Hz, 360 beam sensor
  return {"LDS-01", 360, 2.0 * M_PI, 5.0, 0.0, false, 0.12f, 30.0f};
}

sim::LidarModel modelNamed(const std::string& name) {
  if (name == "ILD26TRI")
    return sim::LidarModel::ild26tri();
  if (name == "LDS-01")
    return lds01();
  return sim::LidarModel::utm30lx360();
}

/// [s] of scans in a recording: long enough that the scans cycle back to the first (which restarts the
/// twist fit's cache, as a bag played in a loop does) rarely, as on a live stream.
constexpr double kRecordingSeconds = 10.0;
/// [s] what the tf feed keeps: all of a recording (the recording's 10.3 s of tf).
constexpr double kKeptSeconds = 2.0 * kRecordingSeconds + 10.0;

/// Scans of one sensor over kRecordingSeconds of the arc, with tf for all of it, fed as the node feeds
/// it (TfFeed: tf2's buffer, and the samples of the one dynamic link).
struct Recording {
  explicit Recording(const sim::LidarModel& lidar)
      : model(lidar),
        trajectory({-2.0, -1.0, 0.3}, 6.0, 5.0),
        tf("odom", "base_link", kKeptSeconds, nullptr) {
    const sim::World world = sim::World::demoRoom();
    geometry_msgs::TransformStamped transform;
    transform.header.frame_id = "base_link";
    transform.child_frame_id = "laser";
    transform.header.stamp = ros_adapter::toRosTime(kEpoch);
    transform.transform = ros_adapter::toTransform(toMrpt(mount));
    tf.add(transform, true);
    transform.header.frame_id = "odom";
    transform.child_frame_id = "base_link";
    for (int k = -5; k <= static_cast<int>(kRecordingSeconds / 0.02) + 10; ++k) {
      const double t = 0.02 * k;
      transform.header.stamp = ros_adapter::toRosTime(kEpoch + core::secondsToNs(t));
      transform.transform = ros_adapter::toTransform(toMrpt(trajectory.pose(t)));
      tf.add(transform, false);
    }
    for (double start = 0.0; start + 1.0 / model.rate <= kRecordingSeconds + 1e-9;
         start += 1.0 / model.rate) {
      simulated.push_back(sim::simulateScan(world, trajectory, mount, model, kEpoch, start));
      sensor_msgs::LaserScan message;
      const core::PlanarScan& scan = simulated.back().scan;
      message.header.stamp = ros_adapter::toRosTime(scan.stamp);
      message.header.frame_id = "laser";
      message.angle_min = scan.angle_min;
      message.angle_max = scan.angle_max;
      message.angle_increment = scan.angle_increment;
      message.time_increment = scan.time_increment;
      message.scan_time = scan.scan_time;
      message.range_min = scan.range_min;
      message.range_max = scan.range_max;
      message.ranges = scan.ranges;
      messages.push_back(message);
    }
  }
  static mrpt::poses::CPose3D toMrpt(const sim::Pose2& pose) {
    return mrpt::poses::CPose3D::FromXYZYawPitchRoll(pose.x, pose.y, 0.0, pose.yaw, 0.0, 0.0);
  }

  sim::LidarModel model;
  sim::ArcTrajectory trajectory;
  sim::Pose2 mount{0.25, 0.05, 0.1};
  ros_adapter::TfFeed tf;
  tf2::BufferCore& buffer = tf.buffer();
  const ros_adapter::TfMotionSource& motion = tf.motion();
  std::vector<sim::SimulatedScan> simulated;
  std::vector<sensor_msgs::LaserScan> messages;
};

Recording& recording(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Recording>> recordings;
  auto& slot = recordings[name];
  if (!slot)
    slot = std::make_unique<Recording>(modelNamed(name));
  return *slot;
}

/// Ours as the node runs it: the mount looked up in tf for every scan, motion from tf (knots or per
/// beam), the message converted and corrected.
void deskewFromTf(Recording& rec, std::size_t k, core::ScanDeskewer& deskewer, core::DeskewedScan& out) {
  const mrpt::poses::CPose3D mount =
      ros_adapter::toPose(rec.buffer.lookupTransform("base_link", "laser", ros::Time(0)).transform);
  const core::PlanarScan scan = ros_adapter::fromMsg(rec.messages[k]);
  deskewer.deskew(scan, core::resolveTiming(scan, {}), mount, rec.motion, out);
}

void laserGeometry(Recording& rec, std::size_t k, laser_geometry::LaserProjection& projector,
                   sensor_msgs::PointCloud2& out) {
  const sensor_msgs::LaserScan& message = rec.messages[k];
  projector.transformLaserScanToPointCloud(message.header.frame_id, message, out, "odom", rec.buffer);
}

void runOurs(benchmark::State& state, const std::string& sensor, double knot_interval,
             core::Interpolation interpolation) {
  Recording& rec = recording(sensor);
  core::DeskewConfig config;
  config.knot_interval = knot_interval;
  config.interpolation = interpolation;
  core::ScanDeskewer deskewer(config);
  core::DeskewedScan out;
  std::size_t k = 0;
  for (auto _ : state) {
    deskewFromTf(rec, k, deskewer, out);
    benchmark::DoNotOptimize(out.points.data());
    k = (k + 1) % rec.messages.size();
  }
  state.counters["beams"] = rec.model.beams;
}

void runLaserGeometry(benchmark::State& state, const std::string& sensor) {
  Recording& rec = recording(sensor);
  laser_geometry::LaserProjection projector;
  sensor_msgs::PointCloud2 out;
  std::size_t k = 0;
  for (auto _ : state) {
    laserGeometry(rec, k, projector, out);
    benchmark::DoNotOptimize(out.data.data());
    k = (k + 1) % rec.messages.size();
  }
  state.counters["beams"] = rec.model.beams;
}

/// What the node does per scan once tf covers it (ScanPipeline::correct without the queue).
void runScanPath(benchmark::State& state, const std::string& sensor) {
  Recording& rec = recording(sensor);
  std::vector<sensor_msgs::LaserScan::ConstPtr> messages;
  for (const sensor_msgs::LaserScan& message : rec.messages)
    messages.push_back(boost::make_shared<sensor_msgs::LaserScan>(message));
  ros_adapter::ScanProcessor processor{ros_adapter::DeskewParams()};
  std::string error;
  std::size_t k = 0;
  for (auto _ : state) {
    const ros_adapter::PreparedScan prepared = processor.prepare(messages[k]);
    // The mount as ScanPipeline looks it up: TfFeed's histories of /tf_static (tf2 only where they do
    // not connect the frames).
    const std::optional<mrpt::poses::CPose3D> mount =
        rec.tf.mount(messages[k]->header.frame_id, prepared.latest(), error);
    if (!mount) {
      state.SkipWithError(("no mount: " + error).c_str());
      break;
    }
    const ros_adapter::DeskewedOutputs outputs = processor.correct(prepared, *mount, rec.motion);
    benchmark::DoNotOptimize(outputs.scan->ranges.data());
    benchmark::DoNotOptimize(outputs.cloud->points.data());
    k = (k + 1) % messages.size();
  }
  state.counters["beams"] = rec.model.beams;
}

/// Google Benchmark's table, then scan_path / laser_geometry per sensor (medians when repeated).
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (bench::isSummaryRun(run))
        times_[run.run_name.function_name] = {run.GetAdjustedRealTime(), run.counters.at("beams").value};
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::printf("\n%-10s %6s %16s %22s %8s\n", "sensor", "beams", "scan_path [us]", "laser_geometry [us]",
                "ratio");
    for (const std::string sensor : {"UTM-30LX", "ILD26TRI", "LDS-01"}) {
      const auto ours = times_.find("scan_path/" + sensor), theirs = times_.find("laser_geometry/" + sensor);
      if (ours == times_.end() || theirs == times_.end())
        continue;
      std::printf("%-10s %6.0f %16.2f %22.2f %8.3f\n", sensor.c_str(), ours->second.second,
                  ours->second.first, theirs->second.first, ours->second.first / theirs->second.first);
    }
  }

 private:
  std::map<std::string, std::pair<double, double>> times_;  // name -> (time [us], beams)
};

void registerAll() {
  // A fixed iteration count (bench/profile.sh: callgrind counts instructions per scan over exactly so
  // many), else Google Benchmark's own.
  const char* const fixed = std::getenv("LIDAR_DESKEW_BENCH_ITERATIONS");
  const auto iterations = [&](benchmark::internal::Benchmark* benchmark) {
    if (fixed != nullptr)
      benchmark->Iterations(std::atoll(fixed));
  };
  for (const std::string sensor : {"UTM-30LX", "ILD26TRI", "LDS-01"}) {
    benchmark::RegisterBenchmark(("ours_knots/" + sensor).c_str(), runOurs, sensor, 0.005,
                                 core::Interpolation::kTwist)
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark(("ours_knots_linear/" + sensor).c_str(), runOurs, sensor, 0.005,
                                 core::Interpolation::kLinear)
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark(("ours_exact/" + sensor).c_str(), runOurs, sensor, 0.0,
                                 core::Interpolation::kTwist)
        ->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark(("laser_geometry/" + sensor).c_str(), runLaserGeometry, sensor)
        ->Unit(benchmark::kMicrosecond);
    iterations(benchmark::RegisterBenchmark(("scan_path/" + sensor).c_str(), runScanPath, sensor)
                   ->Unit(benchmark::kMicrosecond));
  }
}

/// Distance to the true walls of every point of every scan, for each method, and knots vs exact.
void printAccuracy() {
  std::printf("\nAccuracy against truth (noise off), distance to the true walls [mm], all scans of %.0f s:\n",
              kRecordingSeconds);
  std::printf("%-10s %7s | %8s %8s | %8s %8s | %8s %8s | %14s\n", "sensor", "scans", "knots", "max", "exact",
              "max", "l_geom", "max", "knots-exact max");
  for (const std::string sensor : {"UTM-30LX", "ILD26TRI", "LDS-01"}) {
    Recording& rec = recording(sensor);
    const sim::World world = sim::World::demoRoom();
    core::DeskewConfig exact_config;
    exact_config.knot_interval = 0.0;
    core::ScanDeskewer knots, exact(exact_config);
    laser_geometry::LaserProjection projector;
    std::vector<double> knots_d, exact_d, geometry_d;
    double knots_vs_exact = 0.0;
    for (std::size_t k = 0; k < rec.messages.size(); ++k) {
      core::DeskewedScan a, b;
      deskewFromTf(rec, k, knots, a);
      deskewFromTf(rec, k, exact, b);
      const sim::Pose2 laser =
          rec.trajectory.pose(core::nsToSeconds(a.reference_time - kEpoch)).compose(rec.mount);
      for (std::size_t j = 0; j < a.points.size(); ++j) {
        knots_d.push_back(world.distanceTo(laser.apply(a.points[j].position.head<2>())));
        exact_d.push_back(world.distanceTo(laser.apply(b.points[j].position.head<2>())));
        knots_vs_exact = std::max(knots_vs_exact, (a.points[j].position - b.points[j].position).norm());
      }
      sensor_msgs::PointCloud2 cloud;
      laserGeometry(rec, k, projector, cloud);
      const sim::Pose2 laser_at_stamp =
          rec.trajectory.pose(core::nsToSeconds(ros_adapter::toNs(rec.messages[k].header.stamp) - kEpoch))
              .compose(rec.mount);
      for (sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"); x != x.end();
           ++x, ++y) {
        geometry_d.push_back(world.distanceTo(laser_at_stamp.apply({*x, *y})));
      }
    }
    const sim::ErrorStats ka = sim::errorStats(knots_d).scaled(1e3);
    const sim::ErrorStats ea = sim::errorStats(exact_d).scaled(1e3);
    const sim::ErrorStats ga = sim::errorStats(geometry_d).scaled(1e3);
    std::printf("%-10s %7zu | %8.3f %8.3f | %8.3f %8.3f | %8.2f %8.2f | %14.5f\n", sensor.c_str(),
                rec.messages.size(), ka.rms, ka.max, ea.rms, ea.max, ga.rms, ga.max, 1e3 * knots_vs_exact);
  }
}

}  // namespace

int main(int argc, char** argv) {
  registerAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv))
    return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  if (std::getenv("LIDAR_DESKEW_BENCH_NO_ACCURACY") == nullptr)
    printAccuracy();
  return 0;
}
