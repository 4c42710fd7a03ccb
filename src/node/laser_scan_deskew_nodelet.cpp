// lidar_deskew/LaserScanDeskew and lidar_deskew/PointCloudDeskew: the live deskew as nodelets
// (DeskewNode does the work, started through run_node.h).
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "lidar_deskew/core/types.h"
#include "lidar_deskew/node/run_node.h"

namespace lidar_deskew::node {

template <LiveInput input>
class DeskewNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      node_ = startLiveNode(input, getNodeHandle(), getPrivateNodeHandle(), getName());
    } catch (const core::InvalidInput& error) {
      NODELET_FATAL("%s: invalid parameter %s; not started", getName().c_str(), error.what());
      throw;
    }
  }

  std::unique_ptr<LiveNode> node_;
};

using LaserScanDeskewNodelet = DeskewNodelet<LiveInput::kScans>;
using PointCloudDeskewNodelet = DeskewNodelet<LiveInput::kClouds>;

}  // namespace lidar_deskew::node

PLUGINLIB_EXPORT_CLASS(lidar_deskew::node::LaserScanDeskewNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(lidar_deskew::node::PointCloudDeskewNodelet, nodelet::Nodelet)
