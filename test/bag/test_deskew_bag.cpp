// deskew_bag on real bag files: simulated recordings scored against truth (ordinary tf trees, a mount
// re-published mid-recording, a long bag with a tf gap), the real Neato XV-11 recording, bad input and
// the command line as users type it. No roscore.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_msgs/TFMessage.h>

#include <signal.h>
#include <sys/wait.h>

#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>

#include "lidar_deskew/bag/bag_calibrate.h"
#include "lidar_deskew/bag/bag_deskew.h"
#include "lidar_deskew/eval/pair_consistency.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/sim_bag.h"
#include "support/tf_tree.h"
#include "support/temporary.h"

namespace lidar_deskew::bag {
namespace {

using ros_adapter::toNs;
using sim::SimBagOptions;
using sim::writeSimulationBag;

const std::string kNeatoBag = std::string(LIDAR_DESKEW_SOURCE_DIR) + "/data/neato_xv11/test_drive.bag";

std::string temporary(const std::string& name) { return test::temporary("deskew_bag", name); }

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
  options.scan_topics = {"/scan"};
  const BagDeskewSummary summary = deskewBag(options);
  EXPECT_EQ(summary.counters.at("/scan").received, 8u);
  EXPECT_EQ(summary.counters.at("/scan").published, 8u);

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
  // The timing from the data (docs/CALIBRATION.md): the ROS convention makes these scans worse.
  CalibrateOptions calibrate;
  calibrate.input = kNeatoBag;
  calibrate.scan_topic = "/stable_scan";
  const Calibration calibration = calibrateBag(calibrate);
  const core::TimingEstimate& found = calibration.estimate;
  std::printf(
      "Neato timing: first beam - stamp %.2f ms +- %.2f ms (sweep %.2f ms), order %s (%.0f %%); "
      "consistency raw %.1f, message's timing %.1f, estimated %.1f mm\n",
      found.time_offset * 1e3, found.offset_sigma * 1e3, calibration.sweep * 1e3,
      core::toString(found.timing.beam_order).c_str(), 100 * found.order_confidence, found.raw.mean * 1e3,
      found.before.mean * 1e3, found.after.mean * 1e3);
  ASSERT_TRUE(found.told) << found.why;
  EXPECT_EQ(found.timing.beam_order, core::BeamOrder::kAsMessage);
  EXPECT_FALSE(found.period_estimated);  // time_increment agrees with the stamps (5 Hz)
  // The first beam lies before the stamp, within the sweep; the estimate fits better than the message.
  EXPECT_LT(found.time_offset, -3.0 * found.offset_sigma);
  EXPECT_GT(found.time_offset, -calibration.sweep);
  EXPECT_LT(found.after.mean, found.before.mean);
  options.params.timing = found.timing;
  std::string notes;
  options.inform = [&](const std::string& note) { notes += note + "\n"; };
  const BagDeskewSummary summary = deskewBag(options);
  const ros_adapter::PipelineCounters& counters = summary.counters.at("/stable_scan");
  EXPECT_EQ(counters.received, 60u);
  // The first and last scans lie outside the 5-7 Hz odometry: dropped and counted, never extrapolated.
  EXPECT_EQ(counters.published + counters.dropped_tf, 60u);
  EXPECT_GE(counters.published, 55u);
  // One rule, as live: the laser's frame is published on /tf, so its conflicting /tf_static parent is
  // left out and said (with both poses); so is the static base_footprint -> base_link (base_link moves).
  EXPECT_EQ(counters.statics_ignored, 2u);
  EXPECT_NE(notes.find("ignoring /tf_static base_link -> base_laser_link (x 0.000 y 0.000 z 0.130 m"),
            std::string::npos)
      << notes;
  EXPECT_NE(notes.find("base_laser_link moves on /tf (from base_link, x -0.102"), std::string::npos) << notes;
  EXPECT_NE(notes.find("ignoring /tf_static base_footprint -> base_link"), std::string::npos) << notes;

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
  // With that timing, overlapping corrected scans agree better in the odom frame than the raw ones.
  const eval::ConsistencyReport report =
      eval::measureConsistency(output, "/stable_scan", "/stable_scan_deskewed", options.params);
  std::printf(
      "Neato consistency: every pair (%zu) raw %.1f mm, corrected %.1f mm; turning (%zu) raw %.1f, "
      "corrected %.1f\n",
      report.raw.pairs, report.raw.mean * 1e3, report.corrected.mean * 1e3, report.raw_turning.pairs,
      report.raw_turning.mean * 1e3, report.corrected_turning.mean * 1e3);
  EXPECT_GE(report.raw_turning.pairs, 20u);
  EXPECT_EQ(report.raw.pairs, report.corrected.pairs);
  EXPECT_LT(report.corrected_turning.mean, report.raw_turning.mean);
  EXPECT_LT(report.corrected.mean, report.raw.mean);
  std::remove(output.c_str());
}

// The Neato recording with what cost whole bags before: a scan stamped in 2105 (uninitialised: tf2
// threw, deskew_bag and deskew_calibrate exited 1 and wrote nothing), one stamped 0, and a stray
// publisher re-sending odom -> base_link 3 s stale at 2 Hz (each of its messages cleared the tf cache:
// 18 of 23 scans in such a bag). The bad scans are dropped as invalid, the stale tf left out; every other
// scan comes out as from the clean bag, and deskew_calibrate finds the clean bag's timing.
TEST(DeskewBag, BadStampsAndStaleTfCostNoScan) {
  const std::string input = temporary("neato_faults.bag"), output = temporary("neato_faults_out.bag"),
                    clean_output = temporary("neato_clean_out.bag");
  int stale = 0;
  {
    rosbag::Bag in(kNeatoBag, rosbag::bagmode::Read), out(input, rosbag::bagmode::Write);
    std::deque<std::pair<double, geometry_msgs::TransformStamped>> odometry;  // record time, transform
    double next_stray = -1.0;
    int scans = 0;
    for (const rosbag::MessageInstance& message : rosbag::View(in)) {
      out.write(message.getTopic(), message.getTime(), message, message.getConnectionHeader());
      const double now = message.getTime().toSec();
      if (message.getTopic() == "/stable_scan" && (++scans == 10 || scans == 30)) {
        auto bad = message.instantiate<sensor_msgs::LaserScan>();
        bad->header.stamp = scans == 10 ? ros::Time(4'260'211'200, 0) : ros::Time(0, 0);
        out.write("/stable_scan", message.getTime(), *bad);
      }
      if (message.getTopic() != "/tf")
        continue;
      for (const auto& transform : message.instantiate<tf2_msgs::TFMessage>()->transforms) {
        if (transform.child_frame_id == "base_link")
          odometry.emplace_back(now, transform);
      }
      if (next_stray < 0.0)
        next_stray = now + 3.0;
      if (now >= next_stray) {  // the newest odometry at least 3 s old, again
        while (odometry.size() > 1 && odometry[1].first <= now - 3.0)
          odometry.pop_front();
        tf2_msgs::TFMessage stray;
        stray.transforms.push_back(odometry.front().second);
        out.write("/tf", message.getTime(), stray);
        ++stale;
        next_stray += 0.5;
      }
    }
  }
  BagDeskewOptions options;
  options.input = input;
  options.output = output;
  options.scan_topics = {"/stable_scan"};
  std::string notes;
  options.inform = [&](const std::string& note) { notes += note + "\n"; };
  const ros_adapter::PipelineCounters counters = deskewBag(options).counters.at("/stable_scan");
  options.input = kNeatoBag;
  options.output = clean_output;
  const ros_adapter::PipelineCounters clean = deskewBag(options).counters.at("/stable_scan");
  std::printf("Neato with 2 bad stamps and %d stale transforms: %llu of %llu scans corrected (clean: %llu)\n",
              stale, static_cast<unsigned long long>(counters.published),
              static_cast<unsigned long long>(counters.received),
              static_cast<unsigned long long>(clean.published));
  EXPECT_GE(stale, 10);
  EXPECT_EQ(counters.received, clean.received + 2);
  EXPECT_EQ(counters.dropped_invalid, 2u);
  EXPECT_EQ(counters.published, clean.published);
  EXPECT_EQ(counters.dropped_tf, clean.dropped_tf);
  EXPECT_EQ(counters.time_jumps, 0u);
  EXPECT_EQ(counters.stale_tf, static_cast<std::uint64_t>(stale));
  EXPECT_NE(notes.find("invalid stamp"), std::string::npos) << notes;
  EXPECT_NE(notes.find("stale tf from another publisher?"), std::string::npos) << notes;
  // The corrected scans are those of the clean bag, to the bit.
  const auto corrected = read<sensor_msgs::LaserScan>(output, "/stable_scan_deskewed");
  const auto corrected_clean = read<sensor_msgs::LaserScan>(clean_output, "/stable_scan_deskewed");
  ASSERT_EQ(corrected.size(), corrected_clean.size());
  for (std::size_t k = 0; k < corrected.size(); ++k)
    EXPECT_EQ(corrected[k]->ranges, corrected_clean[k]->ranges) << k;

  CalibrateOptions calibrate;
  calibrate.input = input;
  calibrate.scan_topic = "/stable_scan";
  const Calibration calibration = calibrateBag(calibrate);
  calibrate.input = kNeatoBag;
  const Calibration clean_calibration = calibrateBag(calibrate);
  EXPECT_EQ(calibration.estimate.scans, clean_calibration.estimate.scans);
  EXPECT_DOUBLE_EQ(calibration.estimate.time_offset, clean_calibration.estimate.time_offset);
  for (const std::string& path : {input, output, clean_output})
    std::remove(path.c_str());
}

/// The Neato recording with a second publisher of odom -> base_link on another clock: every
/// `period` [s] of record time, the newest odometry stamped `offset` [s] off; `loops` copies of the
/// recording one after the other in record time, their stamps as recorded (a bag recorded while one
/// was played with -l, without --clock). Returns how many stray transforms it wrote.
int writeWithStray(const std::string& path, double offset, double period, int loops = 1) {
  rosbag::Bag in(kNeatoBag, rosbag::bagmode::Read), out(path, rosbag::bagmode::Write);
  int stray = 0;
  rosbag::View view(in);
  const ros::Duration length = view.getEndTime() - view.getBeginTime() + ros::Duration(1.0);
  for (int loop = 0; loop < loops; ++loop) {
    const ros::Duration shift = length * loop;
    std::optional<geometry_msgs::TransformStamped> odometry;  // the newest
    double next_stray = 0.0;
    for (const rosbag::MessageInstance& message : rosbag::View(in)) {
      const ros::Time time = message.getTime() + shift;
      out.write(message.getTopic(), time, message, message.getConnectionHeader());
      if (message.getTopic() == "/tf") {
        const auto transforms = message.instantiate<tf2_msgs::TFMessage>();  // alive through the loop
        for (const auto& transform : transforms->transforms) {
          if (transform.child_frame_id == "base_link")
            odometry = transform;
        }
      }
      if (!odometry || offset == 0.0)
        continue;
      if (next_stray == 0.0)
        next_stray = time.toSec() + 1.0;
      for (; next_stray <= time.toSec(); next_stray += period) {
        tf2_msgs::TFMessage message_out;
        message_out.transforms.push_back(*odometry);
        message_out.transforms.back().header.stamp += ros::Duration(offset);
        out.write("/tf", ros::Time(next_stray), message_out);
        ++stray;
      }
    }
  }
  return stray;
}

// A second publisher of odom -> base_link on another clock, 3 s ahead at 2 Hz or 3 s behind at 200 Hz
// (each of its messages passed for a time jump and cleared the tf cache). The scans' stamps tell the
// real time line: the stray transforms are left out and counted, every scan comes out as from the
// clean bag, bit for bit, and deskew_calibrate (tf 3 s ahead) finds the clean bag's timing from as
// many scans and says what it left out. The recording played twice (stamps going back, record time going on)
// is one jump.
TEST(DeskewBag, StrayPublisherOnAnotherClockCostsNoScan) {
  const std::string clean_output = temporary("stray_clean_out.bag");
  BagDeskewOptions options;
  options.input = kNeatoBag;
  options.output = clean_output;
  options.scan_topics = {"/stable_scan"};
  const ros_adapter::PipelineCounters clean = deskewBag(options).counters.at("/stable_scan");
  const auto corrected_clean = read<sensor_msgs::LaserScan>(clean_output, "/stable_scan_deskewed");
  CalibrateOptions calibrate;
  calibrate.scan_topic = "/stable_scan";
  calibrate.input = kNeatoBag;
  const Calibration clean_calibration = calibrateBag(calibrate);
  std::string notes;
  options.inform = [&](const std::string& note) { notes += note + "\n"; };
  for (const double offset : {3.0, -3.0}) {
    const std::string input = temporary("stray.bag"), output = temporary("stray_out.bag");
    const int stray = writeWithStray(input, offset, offset > 0.0 ? 0.5 : 0.005);
    options.input = input;
    options.output = output;
    notes.clear();
    const ros_adapter::PipelineCounters counters = deskewBag(options).counters.at("/stable_scan");
    std::printf(
        "Neato with %d transforms %+.0f s off: %llu of %llu scans corrected (clean: %llu), %llu jumps\n",
        stray, offset, static_cast<unsigned long long>(counters.published),
        static_cast<unsigned long long>(counters.received), static_cast<unsigned long long>(clean.published),
        static_cast<unsigned long long>(counters.time_jumps));
    EXPECT_GE(stray, offset > 0.0 ? 20 : 2000);
    EXPECT_EQ(counters.time_jumps, 0u) << offset;
    EXPECT_EQ(counters.published, clean.published) << offset;
    EXPECT_EQ(offset > 0.0 ? counters.ahead_tf : counters.stale_tf, static_cast<std::uint64_t>(stray));
    EXPECT_NE(
        notes.find(offset > 0.0 ? "tf ahead from another publisher?" : "stale tf from another publisher?"),
        std::string::npos)
        << notes;
    const auto corrected = read<sensor_msgs::LaserScan>(output, "/stable_scan_deskewed");
    ASSERT_EQ(corrected.size(), corrected_clean.size());
    for (std::size_t k = 0; k < corrected.size(); ++k)
      EXPECT_EQ(corrected[k]->ranges, corrected_clean[k]->ranges) << k;
    std::remove(output.c_str());

    if (offset < 0.0) {  // deskew_calibrate reads tf by the same rules: once is enough (seconds a reading)
      std::remove(input.c_str());
      continue;
    }
    calibrate.input = input;
    const Calibration calibration = calibrateBag(calibrate);
    EXPECT_EQ(calibration.tf_time_jumps, 0u);
    EXPECT_EQ(calibration.tf_stale + calibration.tf_ahead, static_cast<std::size_t>(stray));
    EXPECT_EQ(calibration.estimate.scans, clean_calibration.estimate.scans);
    EXPECT_DOUBLE_EQ(calibration.estimate.time_offset, clean_calibration.estimate.time_offset);
    EXPECT_NE(describe(calibration).find("transforms off the scans' time line left out"), std::string::npos);
    std::remove(input.c_str());
  }
  // Played twice, with the stray publisher: one time jump, the second round corrected as the first
  // (but for its first scan, which waited across the jump).
  const std::string input = temporary("stray_loop.bag"), output = temporary("stray_loop_out.bag");
  writeWithStray(input, 3.0, 0.5, 2);
  options.input = input;
  options.output = output;
  const ros_adapter::PipelineCounters looped = deskewBag(options).counters.at("/stable_scan");
  std::printf("Neato played twice with tf 3 s ahead: %llu of %llu scans corrected, %llu jumps\n",
              static_cast<unsigned long long>(looped.published),
              static_cast<unsigned long long>(looped.received),
              static_cast<unsigned long long>(looped.time_jumps));
  EXPECT_EQ(looped.time_jumps, 1u);
  EXPECT_GE(looped.published + 1, 2 * clean.published);
  for (const std::string& path : {input, output, clean_output})
    std::remove(path.c_str());
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
  // The frame that is missing, and tf's frames (one line, not tf2's dump).
  EXPECT_NE(error.find("fixed_frame 'odom' is unknown to tf; tf's frames: base_footprint,"), std::string::npos)
      << error;
  EXPECT_NE(error.find(" base_link,"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(options.output));
  for (const std::string& path : {truncated, corrupt, no_tf})
    std::remove(path.c_str());
}

/// Writes `drive` as a robot records it: the static links on a latched /tf_static at the start, /tf at
/// 50 Hz from 0.1 s before the first scan to 0.1 s after the last, scans recorded at their sweep's end.
/// `remount(k)` may change the drive's mount (it is then re-published, latched, before scan k);
/// `alter(k, scan)` may spoil scan k.
void writeDriveBag(const std::string& path, test::Drive& drive, int scans,
                   const std::function<bool(int)>& remount = {},
                   const std::function<void(int, sensor_msgs::LaserScan&)>& alter = {}) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  // As `rosbag record` stores a latched publisher's connection (rosbag wants the type fields too).
  using Traits = ros::message_traits::DataType<tf2_msgs::TFMessage>;
  const auto latched = boost::make_shared<ros::M_string>(
      ros::M_string{{"callerid", "/robot_state_publisher"},
                    {"latching", "1"},
                    {"type", Traits::value()},
                    {"md5sum", ros::message_traits::MD5Sum<tf2_msgs::TFMessage>::value()},
                    {"message_definition", ros::message_traits::Definition<tf2_msgs::TFMessage>::value()}});
  const auto writeStatics = [&](double t) {
    tf2_msgs::TFMessage message;
    message.transforms = drive.statics();
    bag.write("/tf_static", drive.stampOf(t), message, latched);
  };
  writeStatics(-0.1);
  const double period = 1.0 / drive.model.rate;
  double tf_until = -0.12;
  for (int k = 0; k < scans; ++k) {
    const double start = 0.1 + k * period;
    if (remount && remount(k))
      writeStatics(start);
    for (; tf_until + 0.02 <= start + period + 1e-9; tf_until += 0.02) {
      tf2_msgs::TFMessage message;
      message.transforms.push_back(drive.motionAt(tf_until + 0.02));
      bag.write("/tf", drive.stampOf(tf_until + 0.02), message);
    }
    const sensor_msgs::LaserScan::Ptr scan = drive.scanAt(start);
    if (alter)
      alter(k, *scan);
    bag.write("/scan", drive.stampOf(start + period), *scan);
  }
  for (int extra = 0; extra < 5; ++extra, tf_until += 0.02) {
    tf2_msgs::TFMessage message;
    message.transforms.push_back(drive.motionAt(tf_until + 0.02));
    bag.write("/tf", drive.stampOf(tf_until + 0.02), message);
  }
}

/// Distances [m] to the true walls of every corrected point in `output`'s /scan_deskewed_points, the
/// laser placed by `drive` (its mount as `mount_at(reference time)` says).
std::vector<double> cloudDistances(const std::string& output, test::Drive drive,
                                   const std::function<sim::Pose2(double)>& mount_at) {
  std::vector<double> distances;
  for (const auto& cloud : read<sensor_msgs::PointCloud2>(output, "/scan_deskewed_points")) {
    drive.mount = mount_at(drive.secondsOf(cloud->header.stamp));
    std::vector<Eigen::Vector2d> points;
    for (sensor_msgs::PointCloud2ConstIterator<float> x(*cloud, "x"), y(*cloud, "y"); x != x.end(); ++x, ++y)
      points.emplace_back(*x, *y);
    struct Xy {
      double x, y;
    };
    std::vector<Xy> xy;
    for (const auto& p : points)
      xy.push_back({p.x(), p.y()});
    for (double d : drive.distances(xy, cloud->header.stamp))
      distances.push_back(d);
  }
  return distances;
}

// A recalibration mid-recording (/tf_static re-published with a new mount): each scan is corrected
// with the mount in force when it was recorded, as the live node does; the output keeps /tf_static
// latched, so a node joining a replay of it gets the mount.
TEST(DeskewBag, MountRepublishedMidRecordingServesTheScansAfterIt) {
  test::Drive drive;
  const sim::Pose2 first = drive.mount, second{0.10, -0.20, 0.5};  // moved 0.26 m, turned 0.4 rad
  const std::string input = temporary("remount.bag"), output = temporary("remount_out.bag");
  writeDriveBag(
      input, drive, 16,
      [&](int k) {
        if (k != 8)
          return false;
        drive.mount = second;
        return true;
      },
      [](int k, sensor_msgs::LaserScan& scan) {
        if (k == 3)
          scan.header.frame_id.clear();  // malformed: dropped, counted
      });
  BagDeskewOptions options;
  options.input = input;
  options.output = output;
  const BagDeskewSummary summary = deskewBag(options);
  EXPECT_EQ(summary.chosen_topics, std::vector<std::string>{"/scan"});
  EXPECT_EQ(summary.counters.at("/scan").published, 15u);
  EXPECT_EQ(summary.counters.at("/scan").dropped_invalid, 1u);
  EXPECT_EQ(summary.counters.at("/scan").mount_changes, 1u);
  const double switch_time = 0.1 + 8 * (1.0 / drive.model.rate);
  const auto errors =
      cloudDistances(output, drive, [&](double t) { return t < switch_time - 1e-6 ? first : second; });
  EXPECT_GT(errors.size(), 15u * 1000u);
  // Every output is written at its own scan's record time (stamps: reference start = the input's).
  {
    std::map<ros::Time, ros::Time> recorded;  // input stamp -> record time
    rosbag::Bag bag(output, rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery("/scan")))
      recorded[message.instantiate<sensor_msgs::LaserScan>()->header.stamp] = message.getTime();
    std::size_t outputs = 0;
    for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery("/scan_deskewed"))) {
      ++outputs;
      EXPECT_EQ(message.getTime(), recorded.at(message.instantiate<sensor_msgs::LaserScan>()->header.stamp));
    }
    EXPECT_EQ(outputs, 15u);
  }
  EXPECT_LT(sim::errorStats(errors).rms, 1e-3);  // one mount for all (0.1.0): decimetres after the switch

  rosbag::Bag bag(output, rosbag::bagmode::Read);
  std::size_t latched = 0;
  for (const rosbag::ConnectionInfo* connection :
       rosbag::View(bag, rosbag::TopicQuery("/tf_static")).getConnections()) {
    const auto latching = connection->header->find("latching");
    latched += latching != connection->header->end() && latching->second == "1";
  }
  EXPECT_GE(latched, 1u);
  std::remove(input.c_str());
  std::remove(output.c_str());
}

// The simulator's recording with a recalibrated mount (issue 24): /tf_static re-published stamped 1.25 ms
// after scan 9's last beam and recorded before it (scan 9 is recorded at its revolution's end). Scan 9 is
// processed after the new mount arrived, yet ended before its stamp: the old mount serves it, the new
// one scan 10 on. Truth in closed form: each scan cast with the mount in force at its last beam.
TEST(DeskewBag, MountChangeServesTheScansEndingAfterItsStamp) {
  sim::Scenario scenario = sim::findScenario("UTM-30LX-270/high/arc");  // a 90 deg blind sector
  const double period = 1.0 / scenario.lidar.rate;
  SimBagOptions sim_options;
  sim_options.mount_change = sim::MountChange{9 * period + scenario.lidar.sweepDuration() + 1.25e-3,
                                              {0.10, -0.20, 0.5}};  // moved 0.26 m and turned 0.4 rad
  const std::string input = temporary("mount_change.bag"), truth_path = temporary("mount_change.truth"),
                    output = temporary("mount_change_out.bag");
  writeSimulationBag(scenario, sim_options, input, truth_path);
  const sim::Truth truth = sim::readTruth(truth_path);
  ASSERT_TRUE(truth.mount_change);
  EXPECT_EQ(truth.mount_change->time, sim_options.mount_change->time);
  // As recorded: the new mount comes before scan 9.
  {
    rosbag::Bag bag(input, rosbag::bagmode::Read);
    std::vector<std::string> order;
    for (const rosbag::MessageInstance& message :
         rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{"/scan", "/tf_static"})))
      order.push_back(message.getTopic());
    ASSERT_EQ(order.size(), 22u);
    EXPECT_EQ(order[10], "/tf_static");  // after the first static and scans 0 to 8
    EXPECT_EQ(order[11], "/scan");
  }
  BagDeskewOptions options;
  options.input = input;
  options.output = output;
  const BagDeskewSummary summary = deskewBag(options);
  EXPECT_EQ(summary.counters.at("/scan").published, 20u);
  EXPECT_EQ(summary.counters.at("/scan").mount_changes, 1u);
  const auto clouds = read<sensor_msgs::PointCloud2>(output, "/scan_deskewed_points");
  ASSERT_EQ(clouds.size(), 20u);
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    const sensor_msgs::PointCloud2& cloud = *clouds[k];
    const core::TimeNs stamp = toNs(cloud.header.stamp);  // the reference time: the first beam
    std::vector<double> distances;
    for (sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"); x != x.end(); ++x, ++y)
      distances.push_back(truth.world.distanceTo(truth.laserPose(stamp).apply({*x, *y})));
    const double error = sim::errorStats(distances).rms;
    if (k == 9 || k == 10)
      std::printf("scan %zu (%s mount): %.4f mm RMS\n", k, k < 10 ? "old" : "new", 1e3 * error);
    EXPECT_GT(distances.size(), 900u) << k;
    EXPECT_LT(error, 1e-3) << k;  // noise off; scan 9 corrected with the new mount: 26.5 mm
  }
  for (const std::string& path : {input, truth_path, output})
    std::remove(path.c_str());
}

// Ordinary trees (docs/FAULTS.md): REP-105 (a static base_footprint -> base_link under a moving
// base_footprint), a mount through a plate, the laser frame as the base frame, leading slashes.
TEST(DeskewBag, OrdinaryTreesAreCorrectedOntoTheTrueWalls) {
  for (const std::string name : {"rep105", "plate", "base", "slash"}) {
    test::Drive drive(test::TfTree::named(name));
    const std::string input = temporary(name + ".bag"), output = temporary(name + "_out.bag");
    writeDriveBag(input, drive, 12);
    BagDeskewOptions options;
    options.input = input;
    options.output = output;
    options.params.fixed_frame = ros_adapter::normalizedFrame(drive.tree.fixed);
    options.params.base_frame = ros_adapter::normalizedFrame(drive.tree.base);
    const BagDeskewSummary summary = deskewBag(options);
    EXPECT_EQ(summary.counters.at("/scan").published, 12u) << name;
    EXPECT_EQ(summary.counters.at("/scan").statics_ignored, 0u) << name;
    const auto errors = cloudDistances(output, drive, [&](double) { return drive.mount; });
    std::printf("%-7s cloud %.3f mm RMS\n", name.c_str(), 1e3 * sim::errorStats(errors).rms);
    EXPECT_LT(sim::errorStats(errors).rms, 1e-3) << name;
    std::remove(input.c_str());
    std::remove(output.c_str());
  }
}

// A long bag (100 s of 50 Hz tf, 5000 samples): the early scans keep their knots (0.1.0 kept the newest
// 4096 sample times of the whole bag: 30 mm RMS in the first 17 s), and a 1 s tf gap early on is
// refused like live, not bridged.
TEST(DeskewBag, LongBagKeepsItsKnotsAndRefusesGaps) {
  const std::string recorded = temporary("long_recorded.bag"), input = temporary("long.bag"),
                    truth_path = temporary("long.truth"), output = temporary("long_out.bag");
  sim::Scenario scenario = sim::findScenario("ILD26TRI/high/arc");
  scenario.duration = 100.0;
  writeSimulationBag(scenario, SimBagOptions(), recorded, truth_path);
  const sim::Truth truth = sim::readTruth(truth_path);
  // Cut the tf between 5 and 6 s after the start.
  double begin = -1.0;
  {
    rosbag::Bag in(recorded, rosbag::bagmode::Read), out(input, rosbag::bagmode::Write);
    for (const rosbag::MessageInstance& message : rosbag::View(in)) {
      if (begin < 0.0)
        begin = message.getTime().toSec();
      const double t = message.getTime().toSec() - begin;
      if (message.getTopic() == "/tf" && t > 5.0 && t < 6.0)
        continue;
      out.write(message.getTopic(), message.getTime(), message, message.getConnectionHeader());
    }
  }
  BagDeskewOptions options;
  options.input = input;
  options.output = output;
  const BagDeskewSummary summary = deskewBag(options);
  const ros_adapter::PipelineCounters& counters = summary.counters.at("/scan");
  EXPECT_EQ(counters.received, 800u);
  EXPECT_GE(counters.tf_gaps, 1u);  // the sweeps across the gap are refused
  EXPECT_EQ(counters.published + counters.dropped_tf, 800u);
  EXPECT_LE(counters.dropped_tf, 12u);
  std::vector<double> early, late;
  for (const auto& cloud : read<sensor_msgs::PointCloud2>(output, "/scan_deskewed_points")) {
    const sim::Pose2 laser = truth.laserPose(toNs(cloud->header.stamp));
    const double t = cloud->header.stamp.toSec() - begin;
    for (sensor_msgs::PointCloud2ConstIterator<float> x(*cloud, "x"), y(*cloud, "y"); x != x.end(); ++x, ++y)
      (t < 17.0 ? early : late).push_back(truth.world.distanceTo(laser.apply({*x, *y})));
  }
  std::printf("long bag: first 17 s %.3f mm RMS (%.1f max), after %.3f mm RMS; %llu tf gaps\n",
              1e3 * sim::errorStats(early).rms, 1e3 * sim::errorStats(early).max,
              1e3 * sim::errorStats(late).rms, static_cast<unsigned long long>(counters.tf_gaps));
  EXPECT_LT(sim::errorStats(early).rms, 1e-3);
  EXPECT_LT(sim::errorStats(early).max, 10e-3);  // no scan bridged the 1 s gap
  EXPECT_LT(sim::errorStats(late).rms, 1e-3);
  for (const std::string& path : {recorded, input, truth_path, output})
    std::remove(path.c_str());
}

/// Runs the deskew_bag executable; returns its exit status and what it printed (stdout and stderr).
int runTool(const std::vector<std::string>& args, std::string& printed,
            const std::function<void(pid_t)>& meanwhile = {}) {
  const std::string log = temporary("tool.log");
  const pid_t pid = fork();
  if (pid == 0) {
    FILE* out = std::freopen(log.c_str(), "w", stdout);
    (void)out;
    dup2(fileno(stdout), fileno(stderr));
    std::vector<char*> argv{const_cast<char*>(LIDAR_DESKEW_BAG_TOOL)};
    for (const std::string& arg : args)
      argv.push_back(const_cast<char*>(arg.c_str()));
    argv.push_back(nullptr);
    execv(LIDAR_DESKEW_BAG_TOOL, argv.data());
    _exit(127);
  }
  if (meanwhile)
    meanwhile(pid);
  int status = 0;
  waitpid(pid, &status, 0);
  std::ifstream in(log);
  printed.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  std::remove(log.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// The command line as users type it.
TEST(DeskewBagTool, CommandLine) {
  std::string printed;
  EXPECT_EQ(runTool({"--help"}, printed), 0);
  EXPECT_NE(printed.find("usage:"), std::string::npos);
  EXPECT_NE(printed.find("tf_timeout"), std::string::npos);  // the parameters are listed

  EXPECT_EQ(runTool({kNeatoBag, temporary("x.bag"), "--tf-timout", "0.1"}, printed), 2);
  EXPECT_NE(printed.find("unknown option --tf-timout"), std::string::npos) << printed;
  EXPECT_EQ(runTool({kNeatoBag, temporary("x.bag"), "--max-extrapolation", "0.1"}, printed), 2);
  EXPECT_NE(printed.find("live node only"), std::string::npos) << printed;

  EXPECT_EQ(runTool({kNeatoBag, temporary("x.bag"), "--scan-topic", "/laser_scan"}, printed), 1);
  EXPECT_NE(printed.find("no LaserScan on /laser_scan; its LaserScan topics: /scan, /stable_scan"),
            std::string::npos)
      << printed;

  const std::string output = temporary("chosen.bag");
  EXPECT_EQ(runTool({kNeatoBag, output, "--stamp-at", "end"}, printed), 0) << printed;
  EXPECT_NE(printed.find("correcting /scan, /stable_scan (the bag's LaserScan topics)"), std::string::npos)
      << printed;
  // The summary has the node's diagnostics counters, by the same names.
  EXPECT_NE(printed.find("/stable_scan: received 60, published 57, passed through 0"), std::string::npos)
      << printed;
  EXPECT_NE(printed.find("dropped: tf 3"), std::string::npos) << printed;
  std::remove(output.c_str());
}

// deskew_calibrate's file as deskew_bag --params reads it: the same timing; the command line wins over
// it; a nested or misspelt file is refused naming the line or the parameter.
TEST(DeskewBagTool, ParamsFileFromTheCalibration) {
  CalibrateOptions calibrate;
  calibrate.input = kNeatoBag;
  calibrate.scan_topic = "/stable_scan";
  const Calibration calibration = calibrateBag(calibrate);
  ASSERT_TRUE(calibration.estimate.told);
  const std::string file = temporary("timing.yaml");
  writeTimingParams(calibration, kNeatoBag, file);
  const ros_adapter::DeskewParams read =
      ros_adapter::DeskewParams::load(ros_adapter::TextParams(ros_adapter::readParamFile(file)));
  EXPECT_EQ(read.timing.time_offset, calibration.estimate.timing.time_offset);
  EXPECT_EQ(read.timing.stamp_at, calibration.estimate.timing.stamp_at);
  EXPECT_EQ(read.timing.beam_order, calibration.estimate.timing.beam_order);
  EXPECT_NEAR(read.timing.time_offset, calibration.estimate.time_offset, 1e-5);  // to 10 us

  std::string printed;
  const std::string output = temporary("with_params.bag");
  EXPECT_EQ(runTool({kNeatoBag, output, "--scan-topic", "/stable_scan", "--params", file, "--consistency"},
                    printed),
            0)
      << printed;
  EXPECT_NE(printed.find("/stable_scan: received 60"), std::string::npos) << printed;
  EXPECT_NE(printed.find("every pair: raw"), std::string::npos) << printed;
  // The node's own parameter file (live-only parameters in it are left out here).
  EXPECT_EQ(
      runTool({kNeatoBag, output, "--params", std::string(LIDAR_DESKEW_SOURCE_DIR) + "/config/deskew.yaml"},
              printed),
      0)
      << printed;
  std::ofstream(file) << "time_offset: -0.1\ntf_timout: 0.1\n";
  EXPECT_EQ(runTool({kNeatoBag, output, "--params", file}, printed), 1);
  EXPECT_NE(printed.find("tf_timout (did you mean tf_timeout?)"), std::string::npos) << printed;
  std::ofstream(file) << "lidar_deskew:\n  time_offset: -0.1\n";
  EXPECT_EQ(runTool({kNeatoBag, output, "--params", file}, printed), 1);
  EXPECT_NE(printed.find(file + ":1: only flat"), std::string::npos) << printed;
  std::remove(file.c_str());
  std::remove(output.c_str());
}

// Ctrl-C or SIGTERM mid-run removes the temporary file; no output, exit 130.
TEST(DeskewBagTool, InterruptedRunLeavesNothingBehind) {
  const std::string input = temporary("interrupt.bag"), truth_path = temporary("interrupt.truth"),
                    output = temporary("interrupt_out.bag");
  sim::Scenario scenario = sim::findScenario("UTM-30LX/normal/arc");
  scenario.duration = 60.0;  // 2400 scans of 1440 beams: about a second of work
  writeSimulationBag(scenario, SimBagOptions(), input, truth_path);
  const std::filesystem::path folder = std::filesystem::path(output).parent_path();
  const auto temporaries = [&] {
    std::size_t count = 0;
    for (const auto& entry : std::filesystem::directory_iterator(folder))
      count += entry.path().filename().string().rfind(
                   std::filesystem::path(output).filename().string() + ".tmp-", 0) == 0;
    return count;
  };
  for (const int signal_number : {SIGINT, SIGTERM}) {
    std::string printed;
    bool seen = false;
    const int status = runTool({input, output, "--quiet"}, printed, [&](pid_t pid) {
      for (int wait = 0; wait < 20000 && !seen; ++wait) {  // up to 20 s for the temporary file to appear
        seen = temporaries() > 0;
        if (!seen)
          usleep(500);
      }
      usleep(20000);
      kill(pid, signal_number);
    });
    EXPECT_TRUE(seen);
    EXPECT_EQ(status, 130) << printed;
    EXPECT_NE(printed.find("interrupted"), std::string::npos) << printed;
    EXPECT_EQ(temporaries(), 0u);
    EXPECT_FALSE(std::filesystem::exists(output));
  }
  std::remove(input.c_str());
  std::remove(truth_path.c_str());
}

/// Writes `drive` as a robot whose tf is recorded `lag` [s] after its stamps (a busy recorder, tf
/// relayed): the statics latched at the start, scans of `scans` revolutions from t = 0 recorded at their
/// sweep's end, /tf at 50 Hz stamped from 0.02 s (inside the first scan) to before the last scan's
/// end, so tf covers every scan but the first and the last.
void writeLateTfBag(const std::string& path, const test::Drive& drive, int scans, double lag) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  tf2_msgs::TFMessage statics;
  statics.transforms = drive.statics();
  bag.write("/tf_static", drive.stampOf(0.0), statics);
  const double period = 1.0 / drive.model.rate;
  for (int k = 0; k < scans; ++k)
    bag.write("/scan", drive.stampOf((k + 1) * period), *drive.scanAt(k * period));
  for (int j = 1; 0.02 * j < scans * period - 0.01; ++j) {
    tf2_msgs::TFMessage message;
    message.transforms.push_back(drive.motionAt(0.02 * j));
    bag.write("/tf", drive.stampOf(0.02 * j + lag), message);
  }
}

// tf recorded 1.5 s after the scans it covers (60 scans wait for it at once): offline every scan tf
// covers is corrected onto the true walls, at the defaults (tf_timeout 0.2 s, queue_size 10 measured
// live) and with a queue that holds the whole recording; the first scan (before tf began) and the last
// (after it ended) are each dropped alone, never with the scans behind them, and the summary names
// both causes with their counts.
TEST(DeskewBag, TfRecordedLateCoversEveryScanAndEachDropIsAlone) {
  const test::Drive drive;
  const int scans = 80;  // 2 s at 40 Hz
  const std::string input = temporary("late_tf.bag"), output = temporary("late_tf_out.bag");
  writeLateTfBag(input, drive, scans, 1.5);
  for (const bool whole_queue : {false, true}) {
    BagDeskewOptions options;
    options.input = input;
    options.output = output;
    if (whole_queue) {
      options.params.queue_size = 1000;
      options.params.tf_timeout = 30.0;
    }
    std::string notes;
    options.inform = [&](const std::string& note) { notes += note + "\n"; };
    const ros_adapter::PipelineCounters counters = deskewBag(options).counters.at("/scan");
    EXPECT_EQ(counters.received, static_cast<std::uint64_t>(scans)) << whole_queue;
    EXPECT_EQ(counters.published, static_cast<std::uint64_t>(scans - 2)) << whole_queue;
    EXPECT_EQ(counters.dropped_tf, 2u) << whole_queue;
    const std::map<std::string, std::uint64_t> causes{{"tf began after the sweep's start", 1},
                                                      {"tf never reached the sweep's end", 1}};
    EXPECT_EQ(counters.dropped_by_cause, causes) << whole_queue;
    // Each cause is said, with its scan's details.
    EXPECT_NE(notes.find("has nothing at the sweep's start"), std::string::npos) << notes;
    EXPECT_NE(notes.find("has not reached the sweep's end"), std::string::npos) << notes;
    const std::vector<double> distances = cloudDistances(output, drive, [&](double) { return drive.mount; });
    EXPECT_EQ(read<sensor_msgs::LaserScan>(output, "/scan_deskewed").size(), std::size_t(scans - 2));
    EXPECT_LT(test::rms(distances), 1e-3) << whole_queue;  // tf's own line between 50 Hz samples
  }
  std::string printed;
  EXPECT_EQ(runTool({input, output, "--quiet"}, printed), 0) << printed;
  EXPECT_NE(printed.find("dropped 2: tf began after the sweep's start (1), tf never reached the sweep's end (1)"),
            std::string::npos)
      << printed;
  std::remove(input.c_str());
  std::remove(output.c_str());
}

// A recording whose header.seq is 0 throughout (a ROS 2 bag converted, some drivers): deskew_bag
// --consistency pairs raw and corrected scans by stamp and order, and measures what it measures on the
// same recording with its seq intact; with reference: end the corrected stamps are not the raw ones.
TEST(DeskewBag, ConsistencyPairsScansWithoutSeq) {
  const std::string unnumbered = temporary("neato_seq0.bag");
  {
    rosbag::Bag in(kNeatoBag, rosbag::bagmode::Read), out(unnumbered, rosbag::bagmode::Write);
    for (const rosbag::MessageInstance& message : rosbag::View(in)) {
      if (message.getTopic() == "/stable_scan") {
        auto scan = message.instantiate<sensor_msgs::LaserScan>();
        scan->header.seq = 0;
        out.write(message.getTopic(), message.getTime(), *scan, message.getConnectionHeader());
      } else {
        out.write(message.getTopic(), message.getTime(), message, message.getConnectionHeader());
      }
    }
  }
  std::vector<eval::ConsistencyReport> reports;
  for (const std::string& input : {kNeatoBag, unnumbered}) {
    BagDeskewOptions options;
    options.input = input;
    options.output = temporary("seq_out.bag");
    options.scan_topics = {"/stable_scan"};
    options.params.deskew.reference = core::Reference::kEnd;
    const ros_adapter::PipelineCounters counters = deskewBag(options).counters.at("/stable_scan");
    EXPECT_EQ(counters.lost_upstream, 0u);
    EXPECT_EQ(counters.published, 57u);
    reports.push_back(eval::measureConsistency(options.output, "/stable_scan", "/stable_scan_deskewed",
                                               options.params));
    std::remove(options.output.c_str());
  }
  std::printf("Neato, reference end: %zu pairs, raw %.2f mm, corrected %.2f mm; seq 0: %zu pairs, %.2f, %.2f\n",
              reports[0].raw.pairs, reports[0].raw.mean * 1e3, reports[0].corrected.mean * 1e3,
              reports[1].raw.pairs, reports[1].raw.mean * 1e3, reports[1].corrected.mean * 1e3);
  EXPECT_GE(reports[0].raw.pairs, 300u);  // every corrected scan paired
  EXPECT_EQ(reports[1].raw.pairs, reports[0].raw.pairs);
  EXPECT_DOUBLE_EQ(reports[1].raw.mean, reports[0].raw.mean);
  EXPECT_DOUBLE_EQ(reports[1].corrected.mean, reports[0].corrected.mean);
  EXPECT_EQ(reports[1].corrected_turning.pairs, reports[0].corrected_turning.pairs);
  std::remove(unnumbered.c_str());
}

}  // namespace
}  // namespace lidar_deskew::bag
