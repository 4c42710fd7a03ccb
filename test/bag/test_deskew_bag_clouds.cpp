// deskew_bag on multi-line recordings, one per driver convention, with no option but the cloud topic:
// the simulator's VLP-16 / OS1-64 sweeps (3D hall, full 3D tf, tilted mount) written as each driver
// writes them; the corrected points scored against the true surfaces with the true sensor pose at the
// output stamp, beside the raw points and one tf lookup per point (exact: true).
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "lidar_deskew/bag/bag_deskew.h"
#include "lidar_deskew/ros/cloud_timing.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/cloud_bag.h"
#include "lidar_deskew/sim/cloud_scenario.h"
#include "support/temporary.h"

namespace lidar_deskew::test {
namespace {

using sim::CloudConvention;

/// The returns of a cloud (x y z float32 at 0, 4, 8; not at the origin, finite).
std::vector<Eigen::Vector3d> returnsOf(const sensor_msgs::PointCloud2& cloud) {
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < static_cast<std::size_t>(cloud.width) * cloud.height; ++i) {
    float xyz[3];
    std::memcpy(xyz, &cloud.data[ros_adapter::pointOffset(cloud, i)], sizeof xyz);
    const Eigen::Vector3d p(xyz[0], xyz[1], xyz[2]);
    if (p.allFinite() && !p.isZero(0.0))
      points.push_back(p);
  }
  return points;
}

std::vector<sensor_msgs::PointCloud2::ConstPtr> cloudsOn(const std::string& bag_path,
                                                         const std::string& topic) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  std::vector<sensor_msgs::PointCloud2::ConstPtr> clouds;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(topic)))
    clouds.push_back(message.instantiate<sensor_msgs::PointCloud2>());
  return clouds;
}

struct Scores {
  double raw = 0.0, ours = 0.0, exact = 0.0;  // [m] RMS distance to the true surfaces
  std::size_t clouds = 0;
  std::vector<std::string> said;  // deskew_bag's notes (not exact run)
};

/// Distances of every output cloud's returns, placed with the true sensor pose at its stamp.
double rmsOf(const std::vector<sensor_msgs::PointCloud2::ConstPtr>& clouds, const sim::CloudTruth& truth,
             const sim::World3& world) {
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& cloud : clouds) {
    const sim::Pose3 pose = truth.sensorPose(ros_adapter::toNs(cloud->header.stamp));
    for (double d : sim::distancesToWorld(world, pose, returnsOf(*cloud))) {
      sum += d * d;
      ++count;
    }
  }
  return count == 0 ? INFINITY : std::sqrt(sum / count);
}

Scores run(const std::string& scenario_name, CloudConvention convention, bool noise,
           const ros_adapter::DeskewParams& params = {}) {
  const std::string name = sim::cloudConventionName(convention);
  const std::string dir = test::temporary("clouds", "");
  const std::string in = dir + name + ".bag", truth_path = dir + name + ".truth";
  sim::CloudBagOptions options;
  options.convention = convention;
  options.noise = noise;
  options.duration = 0.5;
  writeCloudBag(sim::findCloudScenario(scenario_name), options, in, truth_path);
  const sim::CloudTruth truth = sim::readCloudTruth(truth_path);
  const sim::World3 world = sim::World3::byName(truth.world);

  Scores scores;
  for (bool exact : {false, true}) {
    bag::BagDeskewOptions deskew;
    deskew.input = in;
    deskew.output = dir + name + (exact ? "_exact" : "") + "_out.bag";
    deskew.cloud_topics = {"/points"};  // nothing else: the time field is found alone
    deskew.params = params;
    deskew.params.exact = exact;
    if (!exact)
      deskew.inform = [&scores](const std::string& text) { scores.said.push_back(text); };
    deskew.params.deskew.knot_interval = exact ? 0.0 : deskew.params.deskew.knot_interval;
    const bag::BagDeskewSummary summary = bag::deskewBag(deskew);
    const ros_adapter::PipelineCounters& counters = summary.counters.at("/points");
    EXPECT_EQ(counters.published, counters.received) << name;
    const auto outputs = cloudsOn(deskew.output, "/points_deskewed");
    (exact ? scores.exact : scores.ours) = rmsOf(outputs, truth, world);
    if (!exact) {
      scores.clouds = outputs.size();
      // The raw points placed with the pose at the first point: what the correction removes.
      std::vector<sensor_msgs::PointCloud2::ConstPtr> raw = cloudsOn(in, "/points");
      for (std::size_t k = 0; k < raw.size() && k < outputs.size(); ++k) {
        auto placed = boost::make_shared<sensor_msgs::PointCloud2>(*raw[k]);
        placed->header.stamp = outputs[k]->header.stamp;
        raw[k] = placed;
      }
      scores.raw = rmsOf(raw, truth, world);
    }
    std::remove(deskew.output.c_str());
  }
  std::remove(in.c_str());
  std::remove(truth_path.c_str());
  return scores;
}

// Every convention at 6 m/s and 5 rad/s-class motion (the scenarios' "high" cases), noise off: as exact
// as one tf lookup per point, far better than raw.
TEST(DeskewBagClouds, EveryDriverConventionIsCorrectedWithNoOption) {
  for (CloudConvention convention : sim::allCloudConventions()) {
    const bool ouster = convention == CloudConvention::kOuster;
    const std::string scenario = ouster ? "OS1-64/high/arc" : "VLP16/high/arc";
    const Scores scores = run(scenario, convention, false);
    std::printf("%-16s %-16s clouds %zu: raw %.2f mm, ours %.4f mm, one lookup per point %.4f mm RMS\n",
                sim::cloudConventionName(convention).c_str(), scenario.c_str(), scores.clouds,
                1e3 * scores.raw, 1e3 * scores.ours, 1e3 * scores.exact);
    EXPECT_GE(scores.clouds, 4u) << sim::cloudConventionName(convention);
    EXPECT_GT(scores.raw, 20e-3) << sim::cloudConventionName(convention);
    EXPECT_LT(scores.ours, scores.exact + 0.1e-3) << sim::cloudConventionName(convention);
    EXPECT_LT(scores.ours, 1e-3) << sim::cloudConventionName(convention);
    // Which field timed the clouds is said, once: the field each driver writes (sim/cloud_bag.h's table),
    // and for two well-known ones its type, unit and base.
    const std::map<CloudConvention, std::string> field = {
        {CloudConvention::kOuster, "t (uint32, ns, from header.stamp)"},
        {CloudConvention::kVelodyneFirst, "time (float32, s, from header.stamp)"},
        {CloudConvention::kVelodyneLast, "time (float32, s, from header.stamp)"},
        {CloudConvention::kHesai, "timestamp ("},
        {CloudConvention::kRoboSense, "timestamp ("},
        {CloudConvention::kLivox2, "timestamp ("},
        {CloudConvention::kAutoware, "time_stamp ("},
        {CloudConvention::kLivoxCustom, "offset_time ("},
        {CloudConvention::kLaserGeometry, "stamps ("}};
    const std::string expected = "/points: point times from field " + field.at(convention);
    EXPECT_EQ(std::count_if(scores.said.begin(), scores.said.end(),
                            [&](const std::string& line) { return line.rfind(expected, 0) == 0; }),
              1)
        << sim::cloudConventionName(convention) << ": expected " << expected;
  }
}

// A robot on rough ground (pitch, roll and z oscillating: tf fully 3D), noise on: the corrected cloud
// is at the noise floor, as one lookup per point.
TEST(DeskewBagClouds, RoughGroundWithNoise) {
  const Scores scores = run("VLP16/rough/arc", CloudConvention::kVelodyneLast, true);
  std::printf(
      "VLP16/rough/arc velodyne_last noise on: raw %.2f mm, ours %.3f mm, one lookup per point %.3f mm\n",
      1e3 * scores.raw, 1e3 * scores.ours, 1e3 * scores.exact);
  EXPECT_LT(scores.ours, 1.02 * scores.exact);
  EXPECT_LT(scores.ours, scores.raw);
}

// A VLP-16 recording whose clouds carry no time field (velodyne_pointcloud's PointXYZIR, stamped at the
// first point): dropped, naming the fields, unless azimuth_timing is set; with it, as exact as the
// clouds with times.
TEST(DeskewBagClouds, NoTimeFieldWithAzimuthTiming) {
  const std::string dir = test::temporary("clouds", "");
  const std::string in = dir + "no_time.bag", truth_path = dir + "no_time.truth";
  sim::CloudBagOptions options;
  options.convention = CloudConvention::kNoTime;
  options.duration = 0.5;
  writeCloudBag(sim::findCloudScenario("VLP16/high/arc"), options, in, truth_path);
  bag::BagDeskewOptions deskew;
  deskew.input = in;
  deskew.output = dir + "no_time_out.bag";
  deskew.cloud_topics = {"/points"};
  const ros_adapter::PipelineCounters counters = bag::deskewBag(deskew).counters.at("/points");
  EXPECT_GE(counters.received, 4u);
  EXPECT_EQ(counters.published, 0u);
  EXPECT_EQ(counters.dropped_invalid, counters.received);
  std::remove(deskew.output.c_str());

  ros_adapter::DeskewParams params;
  params.azimuth.enabled = true;  // the simulated VLP-16 spins clockwise, stamped at its first point
  const Scores scores = run("VLP16/high/arc", CloudConvention::kNoTime, false, params);
  EXPECT_NE(std::find(scores.said.begin(), scores.said.end(),
                      "/points: point times from the azimuth (no time field)"),
            scores.said.end());
  std::printf("no_time with azimuth_timing: raw %.2f mm, ours %.4f mm, one lookup per point %.4f mm RMS\n",
              1e3 * scores.raw, 1e3 * scores.ours, 1e3 * scores.exact);
  EXPECT_GE(scores.clouds, 4u);
  EXPECT_GT(scores.raw, 20e-3);
  EXPECT_LT(scores.ours, scores.exact + 0.1e-3);
  EXPECT_LT(scores.ours, 1e-3);
  std::remove(in.c_str());
  std::remove(truth_path.c_str());
}

// With cloud_scan: the corrected points of the height band as a planar LaserScan (for gmapping/AMCL),
// each finite bin's endpoint on a true surface (the points' own z left out: a 2 deg tilted mount).
TEST(DeskewBagClouds, PlanarScanOfTheCorrectedPoints) {
  const std::string dir = test::temporary("clouds", "");
  const std::string in = dir + "scan.bag", truth_path = dir + "scan.truth";
  sim::CloudBagOptions options;
  options.convention = CloudConvention::kVelodyneFirst;
  options.duration = 0.5;
  writeCloudBag(sim::findCloudScenario("VLP16/high/arc"), options, in, truth_path);
  const sim::CloudTruth truth = sim::readCloudTruth(truth_path);
  const sim::World3 world = sim::World3::byName(truth.world);
  bag::BagDeskewOptions deskew;
  deskew.input = in;
  deskew.output = dir + "scan_out.bag";
  deskew.cloud_topics = {"/points"};
  deskew.params.cloud_scan.enabled = true;
  bag::deskewBag(deskew);
  rosbag::Bag bag(deskew.output, rosbag::bagmode::Read);
  std::size_t scans = 0, bins = 0, near = 0;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery("/points_deskewed_scan"))) {
    const auto scan = message.instantiate<sensor_msgs::LaserScan>();
    ASSERT_TRUE(scan);
    ++scans;
    EXPECT_EQ(scan->ranges.size(), 1440u);
    std::vector<Eigen::Vector3d> ends;
    for (std::size_t i = 0; i < scan->ranges.size(); ++i) {
      const double r = scan->ranges[i], a = scan->angle_min + i * static_cast<double>(scan->angle_increment);
      if (std::isfinite(r))
        ends.emplace_back(r * std::cos(a), r * std::sin(a), 0.0);
    }
    const auto distances =
        sim::distancesToWorld(world, truth.sensorPose(ros_adapter::toNs(scan->header.stamp)), ends);
    bins += distances.size();
    near += std::count_if(distances.begin(), distances.end(), [](double d) { return d < 20e-3; });
  }
  std::printf(
      "planar scan of the corrected VLP-16 points: %zu scans, %zu bins with a return, %.1f %% within 20 mm\n",
      scans, bins, 100.0 * near / std::max<std::size_t>(1, bins));
  EXPECT_GE(scans, 4u);
  EXPECT_GT(bins, 400 * scans);
  EXPECT_GT(static_cast<double>(near), 0.95 * bins);
  std::remove(in.c_str());
  std::remove(truth_path.c_str());
  std::remove(deskew.output.c_str());
}

}  // namespace
}  // namespace lidar_deskew::test
