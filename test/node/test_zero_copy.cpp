// Zero-copy inside a nodelet manager: this process is the manager (nodelet::Loader) with the real
// lidar_deskew/LaserScanDeskew plugin loaded through pluginlib, and a same-type subscriber here receives
// the very cloud object the nodelet published (pointer identity), not a copy.
#include <gtest/gtest.h>

#include <nodelet/loader.h>
#include <pcl_ros/point_cloud.h>  // the cloud subscribed to as PCL
#include <set>

#include "lidar_deskew/node/laser_scan_deskew_node.h"
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
        received.emplace_back(cloud.get(), node::LaserScanDeskewNode::lastPublishedCloud());
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

// A bad parameter stops the node before it advertises or subscribes anything, naming the parameter.
TEST(Parameters, BadValueIsNamedAndNothingStartsHalfConfigured) {
  ros::NodeHandle nh("bad_params");
  ros::NodeHandle private_nh("bad_params/deskew");
  const auto fieldOf = [&](const std::string& name, const auto& value) -> std::string {
    private_nh.deleteParam("");
    private_nh.setParam(name, value);
    try {
      node::LaserScanDeskewNode node(nh, private_nh, "bad_params");
    } catch (const core::InvalidInput& error) {
      return error.field();
    }
    return "";
  };
  EXPECT_EQ(fieldOf("tf_timeout", -1.0), "tf_timeout");
  EXPECT_EQ(fieldOf("reference", std::string("centre")), "reference");
  EXPECT_EQ(fieldOf("on_tf_failure", std::string("ignore")), "on_tf_failure");
  EXPECT_EQ(fieldOf("knot_interval", std::string("fast")), "knot_interval");
  EXPECT_EQ(fieldOf("base_frame", std::string("odom")), "base_frame");
  EXPECT_EQ(fieldOf("queue_size", 0), "queue_size");
  EXPECT_EQ(fieldOf("queue_size", 2.5), "queue_size");  // not rounded to 2
  EXPECT_EQ(fieldOf("rebin_gap_factor", -2.0), "rebin_gap_factor");
  const auto advertised = [] {
    ros::master::V_TopicInfo topics;
    ros::master::getTopics(topics);
    std::set<std::string> names;
    for (const auto& topic : topics) {
      if (topic.name.rfind("/bad_params/", 0) == 0)
        names.insert(topic.name);
    }
    return names;
  };
  EXPECT_EQ(advertised(), std::set<std::string>{});
  // The check sees a node that did start: a good value advertises both outputs, and the
  // dynamic_reconfigure server its two topics.
  private_nh.deleteParam("");
  private_nh.setParam("tf_timeout", 0.5);
  node::LaserScanDeskewNode node(nh, private_nh, "bad_params");
  EXPECT_EQ(advertised(),
            (std::set<std::string>{"/bad_params/scan_deskewed", "/bad_params/scan_deskewed_points",
                                   "/bad_params/deskew/parameter_descriptions",
                                   "/bad_params/deskew/parameter_updates"}));
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_zero_copy");
  return RUN_ALL_TESTS();
}
