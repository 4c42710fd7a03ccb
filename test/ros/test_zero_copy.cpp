// Zero-copy inside a nodelet manager: this process is the manager (nodelet::Loader) with the real
// lidar_deskew/LaserScanDeskew plugin loaded through pluginlib, and a same-type subscriber here receives
// the very cloud object the nodelet published (pointer identity), not a copy.
#include <gtest/gtest.h>
#include <nodelet/loader.h>

#include "lidar_deskew/ros/deskew_node.h"
#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

TEST(ZeroCopy, SameTypeSubscriberInTheManagerGetsThePublishedObject) {
  nodelet::Loader manager(false);
  const nodelet::M_string remappings;
  const nodelet::V_string arguments;
  ASSERT_TRUE(manager.load("/lidar_deskew", "lidar_deskew/LaserScanDeskew", remappings, arguments));

  LiveRig rig;
  ros::NodeHandle nh;
  std::vector<std::pair<const void*, const void*>> received;  // (received object, last published object)
  const ros::Subscriber subscriber = nh.subscribe<ros_adapter::DeskewedCloud>(
      "scan_deskewed_points", 10, [&](const boost::shared_ptr<const ros_adapter::DeskewedCloud>& cloud) {
        received.emplace_back(cloud.get(), ros_adapter::LaserScanDeskewNode::lastPublishedCloud());
      });
  ASSERT_TRUE(rig.waitFor([&] { return rig.scan_publisher.getNumSubscribers() == 1; }, 5.0));
  rig.publishMount();
  for (int k = 0; k < 3; ++k) {
    const double start = 0.1 + k * 0.025;
    rig.publishTfUntil(start + 0.05);
    rig.publishScan(start);
    ASSERT_TRUE(rig.waitFor([&] { return received.size() == static_cast<std::size_t>(k + 1); }, 5.0));
  }
  for (const auto& [object, published] : received) {
    EXPECT_NE(object, nullptr);
    EXPECT_EQ(object, published);
  }
  manager.unload("/lidar_deskew");
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_zero_copy");
  return RUN_ALL_TESTS();
}
