// lidar_deskew/LaserScanDeskew: the live deskew as a nodelet (LaserScanDeskewNode does the work).
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "lidar_deskew/node/laser_scan_deskew_node.h"

namespace lidar_deskew::node {

class LaserScanDeskewNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      node_ = std::make_unique<LaserScanDeskewNode>(getNodeHandle(), getPrivateNodeHandle(), getName());
    } catch (const core::InvalidInput& error) {
      NODELET_FATAL("%s: invalid parameter %s; not started", getName().c_str(), error.what());
      throw;
    }
  }

  std::unique_ptr<LaserScanDeskewNode> node_;
};

}  // namespace lidar_deskew::node

PLUGINLIB_EXPORT_CLASS(lidar_deskew::node::LaserScanDeskewNodelet, nodelet::Nodelet)
