// deskew_cloud_node: the live deskew of PointCloud2s as a plain node, for robots without a nodelet manager.
#include "lidar_deskew/node/run_node.h"

int main(int argc, char** argv) {
  return lidar_deskew::node::runLiveNode(lidar_deskew::node::LiveInput::kClouds, argc, argv,
                                         "lidar_deskew_cloud");
}
