#include "lidar_deskew/ros/bag_tf.h"

#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

const char* const kTfTopic = "/tf";
const char* const kTfStaticTopic = "/tf_static";

std::string describe(const mrpt::poses::CPose3D& pose) {
  char text[160];
  std::snprintf(text, sizeof text, "x %.3f y %.3f z %.3f m, yaw %.4f pitch %.4f roll %.4f rad", pose.x(),
                pose.y(), pose.z(), pose.yaw(), pose.pitch(), pose.roll());
  return text;
}

bool samePose(const mrpt::poses::CPose3D& a, const mrpt::poses::CPose3D& b) {
  const mrpt::poses::CPose3D difference = (-a) + b;
  const double angle = Eigen::AngleAxisd(difference.getRotationMatrix().asEigen()).angle();
  return std::hypot(difference.x(), difference.y(), difference.z()) < 1e-3 && angle < 1e-3;
}

}  // namespace

rosbag::Bag openForReading(const std::string& path) {
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& error) {
    throw std::runtime_error("cannot read " + path + ": " + error.what());
  }
  return bag;
}

/// The frame of the first message on each scan topic.
std::set<std::string> scanFrames(rosbag::Bag& bag, const std::vector<std::string>& topics) {
  std::set<std::string> frames;
  for (const std::string& topic : topics) {
    for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(topic))) {
      if (const auto scan = message.instantiate<sensor_msgs::LaserScan>()) {
        frames.insert(scan->header.frame_id);
        break;
      }
    }
  }
  return frames;
}

BagTf loadTf(rosbag::Bag& bag, const std::string& bag_path, const std::set<std::string>& scan_frames,
             const DeskewParams& params, MountSource mount_from) {
  std::vector<geometry_msgs::TransformStamped> statics, dynamics;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{kTfTopic, kTfStaticTopic}))) {
    const auto transforms = message.instantiate<tf2_msgs::TFMessage>();
    if (!transforms)
      continue;
    auto& into = message.getTopic() == kTfStaticTopic ? statics : dynamics;
    into.insert(into.end(), transforms->transforms.begin(), transforms->transforms.end());
  }
  const auto isMountLink = [&](const geometry_msgs::TransformStamped& transform) {
    return transform.header.frame_id == params.base_frame && scan_frames.count(transform.child_frame_id) > 0;
  };

  BagTf tf;
  std::ostringstream report;
  for (const std::string& frame : scan_frames) {
    std::optional<mrpt::poses::CPose3D> on_static, on_tf;
    for (const auto& transform : statics) {
      if (isMountLink(transform) && transform.child_frame_id == frame && !on_static)
        on_static = toPose(transform.transform);
    }
    for (const auto& transform : dynamics) {
      if (isMountLink(transform) && transform.child_frame_id == frame && !on_tf)
        on_tf = toPose(transform.transform);
    }
    const std::string link = params.base_frame + " -> " + frame;
    if (!on_static && !on_tf) {
      throw std::runtime_error(bag_path + " has no transform " + link + " (the laser mount) on " + kTfTopic +
                               " or " + kTfStaticTopic);
    }
    const bool use_static = on_static && (mount_from == MountSource::kTfStatic || !on_tf);
    tf.mounts[frame] = use_static ? *on_static : *on_tf;
    if (on_static && on_tf && !samePose(*on_static, *on_tf)) {
      report << "mount " << link << " differs between /tf_static (" << describe(*on_static) << ") and /tf ("
             << describe(*on_tf) << "); using " << (use_static ? "/tf_static" : "/tf") << " (--mount-from "
             << (use_static ? "tf" : "tf_static") << " chooses the other)";
    } else {
      report << "mount " << link << " from " << (use_static ? "/tf_static" : "/tf") << ": "
             << describe(tf.mounts[frame]);
    }
  }

  // A frame that moves on /tf must not also hang from /tf_static: tf2 would then answer one pose for
  // all times (real bags do this, e.g. a URDF's base_footprint -> base_link beside odom -> base_link).
  std::set<std::string> moving;
  for (const auto& transform : dynamics) {
    if (!isMountLink(transform))
      moving.insert(transform.child_frame_id);
  }
  std::set<std::string> ignored;
  for (const auto& transform : statics) {
    if (moving.count(transform.child_frame_id) && ignored.insert(transform.child_frame_id).second) {
      report << "\nignoring /tf_static " << transform.header.frame_id << " -> " << transform.child_frame_id
             << ": " << transform.child_frame_id << " moves on /tf";
    }
  }
  tf.report = report.str();

  rosbag::View everything(bag);
  const double duration = (everything.getEndTime() - everything.getBeginTime()).toSec();
  tf.buffer = std::make_unique<tf2::BufferCore>(ros::Duration(duration + 60.0));
  tf.motion = std::make_unique<TfMotionSource>(*tf.buffer, params.fixed_frame, params.base_frame);
  for (const auto& transform : statics) {
    if (!(isMountLink(transform) && mount_from == MountSource::kTf) &&
        !moving.count(transform.child_frame_id))
      tf.buffer->setTransform(transform, "bag", true);
  }
  for (const auto& transform : dynamics) {
    if (isMountLink(transform))
      continue;  // the mount is taken as chosen above, never from the moving chain
    tf.buffer->setTransform(transform, "bag", false);
    tf.motion->observe(transform);
  }
  if (!tf.buffer->canTransform(params.fixed_frame, params.base_frame, ros::Time(0))) {
    throw std::runtime_error(bag_path + " has no tf from '" + params.fixed_frame + "' to '" +
                             params.base_frame + "' (set fixed_frame / base_frame); frames in its tf:\n" +
                             tf.buffer->allFramesAsString());
  }
  return tf;
}

}  // namespace lidar_deskew::ros_adapter
