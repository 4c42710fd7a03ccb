// lidar_deskew/LaserScanDeskew and lidar_deskew/PointCloudDeskew: the live deskew as nodelets
// (DeskewNode does the work).
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "lidar_deskew/node/laser_scan_deskew_node.h"

namespace lidar_deskew::node {

template <class Node>
class DeskewNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      node_ = std::make_unique<Node>(getNodeHandle(), getPrivateNodeHandle(), getName());
    } catch (const core::InvalidInput& error) {
      NODELET_FATAL("%s: invalid parameter %s; not started", getName().c_str(), error.what());
      throw;
    }
  }

  std::unique_ptr<Node> node_;
};

using LaserScanDeskewNodelet = DeskewNodelet<LaserScanDeskewNode>;
using PointCloudDeskewNodelet = DeskewNodelet<PointCloudDeskewNode>;

}  // namespace lidar_deskew::node

PLUGINLIB_EXPORT_CLASS(lidar_deskew::node::LaserScanDeskewNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(lidar_deskew::node::PointCloudDeskewNodelet, nodelet::Nodelet)
