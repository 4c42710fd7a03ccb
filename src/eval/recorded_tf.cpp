#include "lidar_deskew/eval/recorded_tf.h"

#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::eval {

std::unique_ptr<ros_adapter::TfFeed> loadRecordedTf(rosbag::Bag& bag, const std::string& bag_path,
                                                    const std::string& fixed_frame,
                                                    const std::string& base_frame, std::string* notes,
                                                    const std::vector<std::string>& scan_topics,
                                                    std::map<ros_adapter::TfEvent, std::size_t>* counts) {
  rosbag::View everything(bag);
  const double duration = (everything.getEndTime() - everything.getBeginTime()).toSec();
  auto feed = std::make_unique<ros_adapter::TfFeed>(
      fixed_frame, base_frame, duration + 60.0,
      [notes, counts](ros_adapter::TfEvent event, const std::string& text) {
        if (counts)
          ++(*counts)[event];
        if (notes && event != ros_adapter::TfEvent::kMountFirst)
          *notes += (notes->empty() ? "" : "\n") + text;
      });
  std::vector<std::string> topics{"/tf", "/tf_static"};
  topics.insert(topics.end(), scan_topics.begin(), scan_topics.end());
  for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(topics))) {
    feed->observeClock(ros_adapter::toNs(message.getTime()));
    if (message.getTopic() != "/tf" && message.getTopic() != "/tf_static") {
      const auto scan = message.instantiate<sensor_msgs::LaserScan>();
      if (scan && !scan->header.stamp.isZero())
        feed->observeSweep(ros_adapter::toNs(scan->header.stamp));
      continue;
    }
    if (const auto transforms = message.instantiate<tf2_msgs::TFMessage>()) {
      for (const geometry_msgs::TransformStamped& transform : transforms->transforms)
        feed->add(transform, message.getTopic() == "/tf_static");
    }
  }
  if (const std::string why = feed->whyNoChain(); !why.empty())
    throw std::runtime_error(bag_path + ": " + why + " (set fixed_frame / base_frame)");
  return feed;
}

std::size_t dropStampsTfCannotTake(std::vector<core::PlanarScan>& scans, const ros_adapter::TfFeed& tf) {
  const std::size_t before = scans.size();
  scans.erase(std::remove_if(scans.begin(), scans.end(),
                             [&tf](const core::PlanarScan& scan) {
                               return scan.stamp == 0 ||
                                      tf.coverage(scan.stamp, scan.stamp) == ros_adapter::Coverage::kNever;
                             }),
              scans.end());
  return before - scans.size();
}

}  // namespace lidar_deskew::eval
