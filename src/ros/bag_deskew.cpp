#include "lidar_deskew/ros/bag_deskew.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>

#include "lidar_deskew/ros/bag_tf.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"

namespace lidar_deskew::ros_adapter {
namespace {

std::string canonical(const std::string& path) {
  std::error_code error;
  const std::filesystem::path result = std::filesystem::weakly_canonical(path, error);
  return error ? path : result.string();
}

}  // namespace

BagDeskewSummary deskewBag(const BagDeskewOptions& options) {
  if (options.scan_topics.empty())
    throw std::runtime_error("no scan topic given");
  if (canonical(options.input) == canonical(options.output)) {
    throw std::runtime_error("refusing to write the output over the input (" + options.input + ")");
  }
  rosbag::CompressionType compression = rosbag::compression::Uncompressed;
  if (options.compression == "bz2") {
    compression = rosbag::compression::BZ2;
  } else if (options.compression == "lz4") {
    compression = rosbag::compression::LZ4;
  } else if (options.compression != "none") {
    throw std::runtime_error("compression must be none, bz2 or lz4, got '" + options.compression + "'");
  }
  options.params.validate();

  rosbag::Bag input = openForReading(options.input);
  BagDeskewSummary summary;
  BagTf tf;
  try {
    tf = loadTf(input, options.input, scanFrames(input, options.scan_topics), options.params,
                options.mount_from);
  } catch (const rosbag::BagException& error) {
    throw std::runtime_error("cannot read " + options.input + ": " + error.what());
  }
  summary.mount = tf.report;
  if (options.inform)
    options.inform(tf.report);

  std::map<std::string, std::unique_ptr<ScanProcessor>> processors;
  for (const std::string& topic : options.scan_topics)
    processors[topic] = std::make_unique<ScanProcessor>(options.params);

  const std::string temporary = options.output + ".tmp-" + std::to_string(::getpid());
  try {
    rosbag::Bag output(temporary, rosbag::bagmode::Write);
    output.setCompression(compression);
    rosbag::View view(input);
    const double begin = view.getBeginTime().toSec();
    const double span = std::max(1e-9, view.getEndTime().toSec() - begin);
    auto last_progress = std::chrono::steady_clock::now();
    for (const rosbag::MessageInstance& message : view) {
      const std::string& topic = message.getTopic();
      const auto processor = processors.find(topic);
      if (processor == processors.end()) {
        output.write(topic, message.getTime(), message);
        ++summary.messages;
        continue;
      }
      ++summary.messages;
      ++summary.scans;
      const auto scan = message.instantiate<sensor_msgs::LaserScan>();
      if (!scan) {
        throw std::runtime_error(topic + " carries " + message.getDataType() + ", not sensor_msgs/LaserScan");
      }
      // The scan as read (read once), with its original connection header.
      output.write(options.replace ? topic + "_raw" : topic, message.getTime(), scan,
                   message.getConnectionHeader());
      PreparedScan prepared;
      try {
        prepared = processor->second->prepare(scan);
      } catch (const core::InvalidInput& error) {
        ++summary.dropped_invalid;
        if (options.inform) {
          options.inform("scan at " + std::to_string(scan->header.stamp.toSec()) + " on " + topic +
                         " is malformed: " + error.what());
        }
        continue;
      }
      DeskewedOutputs outputs;
      const auto mount = tf.mounts.find(scan->header.frame_id);
      try {
        if (mount == tf.mounts.end())
          throw core::MotionUnavailable(0, "no mount for frame " + scan->header.frame_id);
        outputs = processor->second->correct(prepared, mount->second, *tf.motion);
        ++summary.corrected;
      } catch (const core::MotionUnavailable& error) {
        if (options.params.on_tf_failure == OnTfFailure::kDrop) {
          ++summary.dropped_tf;
          continue;
        }
        outputs = processor->second->passThrough(prepared);
        ++summary.passed_through;
      }
      output.write(options.replace ? topic : topic + "_deskewed", message.getTime(), *outputs.scan);
      output.write(topic + "_deskewed_points", message.getTime(), *outputs.cloud);

      const auto now = std::chrono::steady_clock::now();
      if (options.progress && now - last_progress > std::chrono::milliseconds(200)) {
        options.progress((message.getTime().toSec() - begin) / span, summary.corrected);
        last_progress = now;
      }
    }
    output.close();
    if (std::rename(temporary.c_str(), options.output.c_str()) != 0) {
      throw std::runtime_error("cannot rename " + temporary + " to " + options.output);
    }
  } catch (const rosbag::BagException& error) {
    std::remove(temporary.c_str());
    throw std::runtime_error("failed reading " + options.input + " or writing " + options.output + ": " +
                             error.what());
  } catch (...) {
    std::remove(temporary.c_str());
    throw;
  }
  if (options.progress)
    options.progress(1.0, summary.corrected);
  return summary;
}

ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic, const DeskewParams& params,
                                     MountSource mount_from, double min_turn, double max_pair,
                                     const std::string& figure_csv) {
  rosbag::Bag bag = openForReading(bag_path);
  const BagTf tf = loadTf(bag, bag_path, scanFrames(bag, {scan_topic}), params, mount_from);
  std::vector<sensor_msgs::LaserScan::ConstPtr> raw, corrected;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{scan_topic, corrected_topic}))) {
    if (const auto scan = message.instantiate<sensor_msgs::LaserScan>())
      (message.getTopic() == scan_topic ? raw : corrected).push_back(scan);
  }
  // Pair each raw scan with its corrected version: the header (seq, frame) is carried over, the stamp
  // becomes the reference time.
  std::map<std::uint32_t, sensor_msgs::LaserScan::ConstPtr> corrected_by_seq;
  for (const auto& scan : corrected)
    corrected_by_seq[scan->header.seq] = scan;
  if (corrected_by_seq.size() != corrected.size()) {
    throw std::runtime_error(bag_path + ": scans on " + scan_topic +
                             " have repeated header.seq; cannot pair them");
  }
  // Points of a scan in the fixed frame, placed with tf at the scan's stamp and the chosen mount.
  const auto inFixedFrame = [&](const sensor_msgs::LaserScan& scan, std::vector<Eigen::Vector2d>& points) {
    points.clear();
    const mrpt::poses::CPose3D laser =
        tf.motion->basePose(toNs(scan.header.stamp)) + tf.mounts.at(scan.header.frame_id);
    for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
      const float range = scan.ranges[i];
      if (!std::isfinite(range) || range <= 0.0f || range < scan.range_min || range > scan.range_max)
        continue;
      const double angle = scan.angle_min + i * static_cast<double>(scan.angle_increment);
      double x, y, z;
      laser.composePoint(range * std::cos(angle), range * std::sin(angle), 0.0, x, y, z);
      points.emplace_back(x, y);
    }
  };
  const auto meanNearest = [&](const std::vector<Eigen::Vector2d>& from,
                               const std::vector<Eigen::Vector2d>& to) {
    double sum = 0.0;
    std::size_t count = 0;
    for (const Eigen::Vector2d& p : from) {
      double nearest = INFINITY;
      for (const Eigen::Vector2d& q : to)
        nearest = std::min(nearest, (p - q).squaredNorm());
      nearest = std::sqrt(nearest);
      if (nearest <= max_pair) {
        sum += nearest;
        ++count;
      }
    }
    return count ? sum / count : -1.0;
  };

  ConsistencyReport report;
  double raw_sum = 0.0, corrected_sum = 0.0, largest_turn = 0.0;
  std::vector<Eigen::Vector2d> raw_a, raw_b, corrected_a, corrected_b;
  for (std::size_t k = 0; k + 1 < raw.size(); ++k) {
    const auto first = corrected_by_seq.find(raw[k]->header.seq);
    const auto second = corrected_by_seq.find(raw[k + 1]->header.seq);
    if (first == corrected_by_seq.end() || second == corrected_by_seq.end())
      continue;  // not corrected (no tf)
    double turn;
    try {
      const double yaw_a = tf.motion->basePose(toNs(raw[k]->header.stamp)).yaw();
      const double yaw_b = tf.motion->basePose(toNs(raw[k + 1]->header.stamp)).yaw();
      turn = std::abs(std::remainder(yaw_b - yaw_a, 2.0 * M_PI));
      if (turn < min_turn)
        continue;
      inFixedFrame(*raw[k], raw_a);
      inFixedFrame(*raw[k + 1], raw_b);
      inFixedFrame(*first->second, corrected_a);
      inFixedFrame(*second->second, corrected_b);
    } catch (const core::MotionUnavailable&) {
      continue;  // tf does not cover this pair
    }
    const double raw_distance = meanNearest(raw_b, raw_a);
    const double corrected_distance = meanNearest(corrected_b, corrected_a);
    if (raw_distance < 0.0 || corrected_distance < 0.0)
      continue;
    raw_sum += raw_distance;
    corrected_sum += corrected_distance;
    ++report.turning_pairs;
    if (!figure_csv.empty() && turn > largest_turn) {
      largest_turn = turn;
      std::ofstream out(figure_csv);
      out << "kind,x,y\n";
      for (const auto& [kind, points] :
           {std::pair{"raw_a", &raw_a}, std::pair{"raw_b", &raw_b}, std::pair{"corrected_a", &corrected_a},
            std::pair{"corrected_b", &corrected_b}}) {
        for (const Eigen::Vector2d& p : *points)
          out << kind << "," << p.x() << "," << p.y() << "\n";
      }
    }
  }
  if (report.turning_pairs) {
    report.raw_mm = 1e3 * raw_sum / report.turning_pairs;
    report.corrected_mm = 1e3 * corrected_sum / report.turning_pairs;
  }
  return report;
}

}  // namespace lidar_deskew::ros_adapter
