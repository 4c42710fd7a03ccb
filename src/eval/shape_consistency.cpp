#include "lidar_deskew/eval/shape_consistency.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::eval {

ShapeReport measureShapes(const std::string& bag_path, const std::string& scan_topic,
                          const ros_adapter::DeskewParams& params, const core::ShapeConfig& config) {
  rosbag::Bag bag = ros_adapter::openBagForReading(bag_path);
  std::vector<core::PlanarScan> scans;
  std::string frame;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{scan_topic}))) {
    const auto scan = message.instantiate<sensor_msgs::LaserScan>();
    if (!scan)
      continue;
    core::PlanarScan planar = ros_adapter::fromMsg(*scan);
    try {
      core::validateScan(planar);
    } catch (const core::InvalidInput&) {
      continue;  // malformed: the node drops it too
    }
    if (frame.empty())
      frame = ros_adapter::normalizedFrame(scan->header.frame_id);
    scans.push_back(std::move(planar));
  }
  if (scans.empty())
    throw std::runtime_error(bag_path + ": no valid LaserScan on " + scan_topic);
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      loadRecordedTf(bag, bag_path, params.fixed_frame, params.base_frame);
  dropStampsTfCannotTake(scans, *tf);
  std::stable_sort(scans.begin(), scans.end(),
                   [](const core::PlanarScan& a, const core::PlanarScan& b) { return a.stamp < b.stamp; });
  std::string error;
  const auto mount = tf->mount(frame, error);
  if (!mount)
    throw std::runtime_error(bag_path + ": no laser mount: " + error);
  ShapeReport report;
  report.scans = scans.size();
  core::ShapeVerdict verdict =
      core::checkShapes(std::move(scans), *mount, tf->motion(), params.timing, params.deskew, config);
  report.shapes = verdict.shapes;
  report.rotation = verdict.rotation;
  report.warnings = std::move(verdict.warnings);
  return report;
}

std::string formatShapes(const core::ShapeRatio& shapes) {
  if (shapes.pairs == 0)
    return "no pairs";
  char text[160];
  std::snprintf(
      text, sizeof text,
      "%.2f (quartiles %.2f-%.2f; median aligned distance raw %.1f mm, corrected %.1f mm; %zu pairs)",
      shapes.ratio, shapes.ratio_low, shapes.ratio_high, shapes.raw * 1e3, shapes.corrected * 1e3,
      shapes.pairs);
  return text;
}

std::string formatRotation(const core::RotationAgreement& rotation) {
  if (rotation.turning_pairs == 0 || !std::isfinite(rotation.scale))
    return "no turning pairs (" + std::to_string(rotation.pairs) + " pairs)";
  char text[200];
  std::snprintf(text, sizeof text,
                "%.2f (correlation %.2f; %zu pairs, %zu turning); best with tf read at the scans' times "
                "%+.0f ms: %.2f (correlation %.2f)",
                rotation.scale, rotation.correlation, rotation.pairs, rotation.turning_pairs,
                rotation.lag * 1e3, rotation.lag_scale, rotation.lag_correlation);
  return text;
}

}  // namespace lidar_deskew::eval
