// The live deskew's entry points for the plain nodes and the nodelets, declared without the node's own
// headers (ROS, PCL, diagnostics, the pipeline): their sources compile against this alone, and
// DeskewNode is built once, in the node library.
#pragma once

#include <memory>
#include <string>

namespace ros {
class NodeHandle;
}

namespace lidar_deskew::node {

/// Which DeskewNode: LaserScans (DeskewNode<ScanProcessor>) or PointCloud2s (<CloudProcessor>).
enum class LiveInput { kScans, kClouds };

/// A running DeskewNode of either input, owned by a nodelet; deleting it stops the node.
class LiveNode {
 public:
  virtual ~LiveNode() = default;
};

/// Starts the live deskew of `input` (DeskewNode's constructor: throws core::InvalidInput naming a bad
/// parameter).
std::unique_ptr<LiveNode> startLiveNode(LiveInput input, const ros::NodeHandle& nh,
                                        const ros::NodeHandle& private_nh, const std::string& name);

/// The plain nodes' main: ros::init (node name `default_name` unless remapped), one node spun until
/// shutdown; 0, or 1 when a parameter is invalid (logged).
int runLiveNode(LiveInput input, int argc, char** argv, const char* default_name);

}  // namespace lidar_deskew::node
