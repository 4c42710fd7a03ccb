// deskew_bag on real bag files: a simulated recording scored against truth, the real Neato XV-11
// recording, and bad input. No roscore.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include "lidar_deskew/ros/bag_deskew.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/sim_bag.h"

namespace lidar_deskew::ros_adapter {
namespace {

const std::string kNeatoBag = std::string(LIDAR_DESKEW_SOURCE_DIR) + "/data/neato_xv11/test_drive.bag";

std::string temporary(const std::string& name) {
  return ::testing::TempDir() + "/deskew_bag_" + std::to_string(::getpid()) + "_" + name;
}

std::map<std::string, std::size_t> topicCounts(const std::string& path) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::map<std::string, std::size_t> counts;
  for (const rosbag::MessageInstance& message : rosbag::View(bag))
    ++counts[message.getTopic()];
  return counts;
}

template <typename M>
std::vector<boost::shared_ptr<M>> read(const std::string& path, const std::string& topic) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::vector<boost::shared_ptr<M>> messages;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(topic)))
    messages.push_back(message.instantiate<M>());
  return messages;
}

std::string errorOf(const BagDeskewOptions& options) {
  try {
    deskewBag(options);
  } catch (const std::runtime_error& error) {
    return error.what();
  }
  return "";
}

TEST(DeskewBag, SimulatedRecordingAgainstTruth) {
  const std::string input = temporary("sim.bag"), truth_path = temporary("sim.truth"),
                    output = temporary("out.bag");
  writeSimulationBag(sim::findScenario("ILD26TRI/normal/arc"), SimBagOptions(), input, truth_path);
  BagDeskewOptions options;
  options.input = input;
  options.output = output;
  const BagDeskewSummary summary = deskewBag(options);
  EXPECT_EQ(summary.scans, 8u);
  EXPECT_EQ(summary.corrected, 8u);

  // Every input message is there unchanged in number, plus the two outputs per scan.
  const auto in = topicCounts(input), out = topicCounts(output);
  for (const auto& [topic, count] : in)
    EXPECT_EQ(out.at(topic), count) << topic;
  EXPECT_EQ(out.at("/scan_deskewed"), 8u);
  EXPECT_EQ(out.at("/scan_deskewed_points"), 8u);

  // The written clouds lie on the true walls (noise off: < 0.5 mm RMS; raw is decimetres).
  const sim::Truth truth = sim::readTruth(truth_path);
  std::vector<double> distances;
  for (const auto& cloud : read<sensor_msgs::PointCloud2>(output, "/scan_deskewed_points")) {
    const sim::Pose2 laser = truth.laserPose(toNs(cloud->header.stamp));
    for (sensor_msgs::PointCloud2ConstIterator<float> x(*cloud, "x"), y(*cloud, "y"); x != x.end();
         ++x, ++y) {
      distances.push_back(truth.world.distanceTo(laser.apply({*x, *y})));
    }
  }
  EXPECT_GT(distances.size(), 8u * 300u);
  EXPECT_LT(sim::errorStats(distances).rms, 0.5e-3);
  // The corrected scans keep the input grid.
  const auto raw = read<sensor_msgs::LaserScan>(output, "/scan");
  const auto corrected = read<sensor_msgs::LaserScan>(output, "/scan_deskewed");
  ASSERT_EQ(raw.size(), corrected.size());
  for (std::size_t k = 0; k < raw.size(); ++k) {
    EXPECT_EQ(corrected[k]->ranges.size(), raw[k]->ranges.size());
    EXPECT_EQ(corrected[k]->angle_min, raw[k]->angle_min);
    EXPECT_EQ(corrected[k]->angle_increment, raw[k]->angle_increment);
  }

  // --replace: the corrected scan under the original name, the raw one kept as /scan_raw; compressed.
  for (const std::string compression : {"bz2", "lz4"}) {
    options.replace = true;
    options.compression = compression;
    options.output = temporary("replace.bag");
    deskewBag(options);
    const auto replaced = topicCounts(options.output);
    EXPECT_EQ(replaced.at("/scan"), 8u);
    EXPECT_EQ(replaced.at("/scan_raw"), 8u);
    EXPECT_EQ(read<sensor_msgs::LaserScan>(options.output, "/scan").front()->time_increment, 0.0f);
    EXPECT_NE(read<sensor_msgs::LaserScan>(options.output, "/scan_raw").front()->time_increment, 0.0f);
    std::remove(options.output.c_str());
  }
  std::remove(input.c_str());
  std::remove(truth_path.c_str());
  std::remove(output.c_str());
}

TEST(DeskewBag, RealNeatoRecording) {
  const std::string output = temporary("neato.bag");
  BagDeskewOptions options;
  options.input = kNeatoBag;
  options.output = output;
  options.scan_topics = {"/stable_scan"};
  options.mount_from = MountSource::kTf;
  options.params.timing.stamp_at = core::StampAt::kEnd;
  std::vector<std::string> notes;
  options.inform = [&](const std::string& note) { notes.push_back(note); };
  const BagDeskewSummary summary = deskewBag(options);
  EXPECT_EQ(summary.scans, 60u);
  // The first and last scans lie outside the 5-7 Hz odometry: dropped and counted, never extrapolated.
  EXPECT_EQ(summary.corrected + summary.dropped_tf, 60u);
  EXPECT_GE(summary.corrected, 55u);
  // The conflicting mounts are reported, and which one was used.
  ASSERT_FALSE(notes.empty());
  EXPECT_NE(notes.front().find("differs between /tf_static"), std::string::npos) << notes.front();
  EXPECT_NE(notes.front().find("using /tf"), std::string::npos);
  EXPECT_NE(summary.mount.find("ignoring /tf_static base_footprint -> base_link"), std::string::npos);

  const auto in = topicCounts(kNeatoBag), out = topicCounts(output);
  for (const auto& [topic, count] : in)
    EXPECT_EQ(out.at(topic), count) << topic;
  const auto raw = read<sensor_msgs::LaserScan>(output, "/stable_scan");
  std::map<std::uint32_t, sensor_msgs::LaserScan::ConstPtr> raw_by_seq;
  for (const auto& scan : raw)
    raw_by_seq[scan->header.seq] = scan;
  for (const auto& scan : read<sensor_msgs::LaserScan>(output, "/stable_scan_deskewed")) {
    const auto& input = raw_by_seq.at(scan->header.seq);
    EXPECT_EQ(scan->ranges.size(), input->ranges.size());  // the grid gmapping was given
    EXPECT_EQ(scan->angle_min, input->angle_min);
    EXPECT_EQ(scan->angle_increment, input->angle_increment);
    for (float range : scan->ranges)
      EXPECT_FALSE(std::isnan(range));
  }
  for (const auto& cloud : read<sensor_msgs::PointCloud2>(output, "/stable_scan_deskewed_points")) {
    for (sensor_msgs::PointCloud2ConstIterator<float> x(*cloud, "x"); x != x.end(); ++x) {
      EXPECT_TRUE(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]));
    }
  }
  // While turning, consecutive corrected scans agree better in the odom frame than the raw ones.
  const ConsistencyReport report =
      measureConsistency(output, "/stable_scan", "/stable_scan_deskewed", options.params, options.mount_from);
  std::printf("Neato turning pairs %zu: raw %.1f mm, corrected %.1f mm\n", report.turning_pairs,
              report.raw_mm, report.corrected_mm);
  EXPECT_GE(report.turning_pairs, 5u);
  EXPECT_LT(report.corrected_mm, report.raw_mm);
  std::remove(output.c_str());
}

TEST(DeskewBag, BadInputGivesAClearErrorAndNoOutput) {
  BagDeskewOptions options;
  options.scan_topics = {"/stable_scan"};
  // The output over the input.
  options.input = kNeatoBag;
  options.output = kNeatoBag;
  EXPECT_NE(errorOf(options).find("refusing"), std::string::npos);

  // A truncated bag and a corrupt one.
  const std::string truncated = temporary("truncated.bag"), corrupt = temporary("corrupt.bag");
  {
    std::ifstream in(kNeatoBag, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    for (std::size_t i = 4096; i < bytes.size(); i += 97)
      bytes[i] = static_cast<char>(bytes[i] ^ 0x5a);
    std::ofstream(corrupt, std::ios::binary) << bytes;
  }
  for (const std::string& input : {truncated, corrupt, temporary("missing.bag")}) {
    options.input = input;
    options.output = temporary("bad_out.bag");
    const std::string error = errorOf(options);
    EXPECT_FALSE(error.empty()) << input;
    EXPECT_FALSE(std::filesystem::exists(options.output)) << input;
    std::printf("%s: %s\n", input.c_str(), error.c_str());
  }

  // A bag without the motion's tf: the error names the frames.
  const std::string no_tf = temporary("no_tf.bag");
  {
    rosbag::Bag bag(no_tf, rosbag::bagmode::Write);
    rosbag::Bag in(kNeatoBag, rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& message : rosbag::View(in)) {
      if (message.getTopic() != "/tf")
        bag.write(message.getTopic(), message.getTime(), message);
    }
    // keep the mount, on /tf_static
  }
  options.input = no_tf;
  const std::string error = errorOf(options);
  EXPECT_NE(error.find("'odom'"), std::string::npos) << error;
  EXPECT_NE(error.find("'base_link'"), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(options.output));
  for (const std::string& path : {truncated, corrupt, no_tf})
    std::remove(path.c_str());
}

}  // namespace
}  // namespace lidar_deskew::ros_adapter
