#include "lidar_deskew/eval/consistency.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <Eigen/Core>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <vector>

#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::eval {

using ros_adapter::toNs;

ConsistencyReport measureConsistency(const std::string& bag_path, const std::string& scan_topic,
                                     const std::string& corrected_topic,
                                     const ros_adapter::DeskewParams& params, double min_turn,
                                     double max_pair, const std::string& figure_csv) {
  rosbag::Bag bag = ros_adapter::openBagForReading(bag_path);
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      loadRecordedTf(bag, bag_path, params.fixed_frame, params.base_frame);
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
    std::string error;
    const auto mount = tf->mount(ros_adapter::normalizedFrame(scan.header.frame_id), error);
    if (!mount)
      throw std::runtime_error(bag_path + ": no laser mount: " + error);
    const mrpt::poses::CPose3D laser = tf->motion().basePose(toNs(scan.header.stamp)) + *mount;
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
      const double yaw_a = tf->motion().basePose(toNs(raw[k]->header.stamp)).yaw();
      const double yaw_b = tf->motion().basePose(toNs(raw[k + 1]->header.stamp)).yaw();
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

}  // namespace lidar_deskew::eval
