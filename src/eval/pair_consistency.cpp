#include "lidar_deskew/eval/pair_consistency.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <memory>
#include <vector>

#include "lidar_deskew/core/timing_fit.h"
#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"

namespace lidar_deskew::eval {

using ros_adapter::toNs;

std::string formatConsistency(const core::ConsistencySummary& summary) {
  char text[96];
  std::snprintf(text, sizeof text, "%.1f mm (spread %.1f, %zu pairs)", summary.mean * 1e3,
                summary.spread * 1e3, summary.pairs);
  return text;
}

ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic,
                                     const ros_adapter::DeskewParams& params, double turning_rate,
                                     const std::string& figure_csv) {
  rosbag::Bag bag = ros_adapter::openBagForReading(bag_path);
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      loadRecordedTf(bag, bag_path, params.fixed_frame, params.base_frame, nullptr, {scan_topic});
  std::vector<sensor_msgs::LaserScan::ConstPtr> raw, corrected;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{scan_topic, corrected_topic}))) {
    if (const auto scan = message.instantiate<sensor_msgs::LaserScan>())
      (message.getTopic() == scan_topic ? raw : corrected).push_back(scan);
  }
  // Pair each raw scan with its corrected version by stamp and order: the corrected one is stamped at
  // the raw one's reference time (on whole microseconds), in the same frame. header.seq cannot pair
  // them: ROS 2 conversions and some drivers leave it 0 or repeat it.
  std::map<std::pair<std::string, core::TimeNs>, std::deque<sensor_msgs::LaserScan::ConstPtr>> corrected_by_stamp;
  for (const auto& scan : corrected)
    corrected_by_stamp[{scan->header.frame_id, toNs(scan->header.stamp)}].push_back(scan);
  const ros_adapter::ScanProcessor processor(params);
  const auto correctedOf = [&](const sensor_msgs::LaserScan::ConstPtr& scan) -> sensor_msgs::LaserScan::ConstPtr {
    core::TimeNs reference = 0;
    try {
      reference = processor.prepare(scan).timing.referenceTime(params.deskew.reference);
    } catch (const std::exception&) {
      return nullptr;  // malformed: not corrected
    }
    constexpr core::TimeNs kMicrosecond = 1000;
    auto match = corrected_by_stamp.lower_bound({scan->header.frame_id, reference - kMicrosecond});
    if (match == corrected_by_stamp.end() || match->first.first != scan->header.frame_id ||
        match->first.second > reference + kMicrosecond)
      return nullptr;
    const sensor_msgs::LaserScan::ConstPtr found = match->second.front();
    match->second.pop_front();
    if (match->second.empty())
      corrected_by_stamp.erase(match);
    return found;
  };
  // A scan's ranges in the fixed frame, every beam placed with tf at the scan's stamp.
  const auto place = [&](const sensor_msgs::LaserScan& scan) {
    std::string error;
    const core::TimeNs stamp = toNs(scan.header.stamp);
    // The mount in force at the stamp (the deskew takes it at the sweep's end: they differ only for a
    // sweep across a re-published mount's stamp).
    const auto mount = tf->mount(ros_adapter::normalizedFrame(scan.header.frame_id), stamp, error);
    if (!mount)
      throw std::runtime_error(bag_path + ": no laser mount: " + error);
    return core::placeRaw(ros_adapter::fromMsg(scan), tf->motion().basePose(stamp) + *mount, stamp);
  };
  std::vector<core::PlacedScan> raw_placed, corrected_placed;
  std::vector<double> turn_rates;
  for (const auto& scan : raw) {
    const sensor_msgs::LaserScan::ConstPtr match = correctedOf(scan);
    if (!match || scan->ranges.empty() || scan->angle_increment == 0.0f)
      continue;  // not corrected (no tf)
    try {
      const core::TimeNs start = toNs(scan->header.stamp);
      // The turn over one revolution (the message's period; 0.1 s when it has none).
      const double period = core::messagePeriod(ros_adapter::fromMsg(*scan));
      const double span = period > 0.0 ? period : 0.1;
      const double turn_rate = core::turnRate(tf->motion(), start, start + core::secondsToNs(span));
      core::PlacedScan placed_raw = place(*scan);
      core::PlacedScan placed_corrected = place(*match);
      raw_placed.push_back(std::move(placed_raw));
      corrected_placed.push_back(std::move(placed_corrected));
      turn_rates.push_back(std::abs(turn_rate));
    } catch (const core::MotionUnavailable&) {
      continue;  // tf does not cover this scan
    }
  }
  const core::ConsistencyConfig config;
  const auto pairs = core::overlappingPairs(corrected_placed, core::PairSelection(), config);
  std::vector<double> raw_all, corrected_all, raw_turning, corrected_turning;
  double largest_turn = -1.0;
  std::size_t figure_pair = pairs.size();
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const auto [earlier, later] = pairs[p];
    const double raw_distance = core::pairDistance(raw_placed[later], raw_placed[earlier], config);
    const double corrected_distance =
        core::pairDistance(corrected_placed[later], corrected_placed[earlier], config);
    raw_all.push_back(raw_distance);
    corrected_all.push_back(corrected_distance);
    const double turn = std::max(turn_rates[earlier], turn_rates[later]);
    if (turn >= turning_rate) {
      raw_turning.push_back(raw_distance);
      corrected_turning.push_back(corrected_distance);
    }
    if (turn > largest_turn) {
      largest_turn = turn;
      figure_pair = p;
    }
  }
  if (!figure_csv.empty() && figure_pair < pairs.size()) {
    const auto [a, b] = pairs[figure_pair];
    std::ofstream out(figure_csv);
    out << "kind,x,y\n";
    for (const auto& [kind, scan] :
         {std::pair{"raw_a", &raw_placed[a]}, std::pair{"raw_b", &raw_placed[b]},
          std::pair{"corrected_a", &corrected_placed[a]}, std::pair{"corrected_b", &corrected_placed[b]}}) {
      for (const Eigen::Vector2d& point : scan->points())
        out << kind << "," << point.x() << "," << point.y() << "\n";
    }
  }
  ConsistencyReport report;
  report.raw = core::summarize(raw_all);
  report.corrected = core::summarize(corrected_all);
  report.raw_turning = core::summarize(raw_turning);
  report.corrected_turning = core::summarize(corrected_turning);
  return report;
}

}  // namespace lidar_deskew::eval
