// Ordinary tf trees through the live deskew (real roscore): run by rostest once per tree, the tree
// named by the private parameter `tree`:
//   rep105  odom -> base_footprint on /tf, base_footprint -> base_link on /tf_static (a TurtleBot3),
//           base_frame base_link
//   plate   the mount through an intermediate frame: base_link -> plate -> laser
//   base    the laser's frame is the base frame (no mount transform at all)
//   slash   every frame id with a leading slash, fixed_frame '/odom'
// The driver plays the simulator's 6 m/s, 5 rad/s arc at 50 Hz tf with UTM-30LX scans (40 Hz).
#include <gtest/gtest.h>

#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

constexpr double kScanPeriod = 1.0 / 40.0;

TEST(Trees, EveryScanIsCorrectedOntoTheTrueWalls) {
  std::string name;
  ros::NodeHandle("~").getParam("tree", name);
  LiveRig rig;
  rig.useTree(TfTree::named(name));
  if (name == "base")
    rig.mount = {0.0, 0.0, 0.0};  // the laser is the base
  ASSERT_TRUE(rig.connect());
  std::vector<double> cloud_errors, raw_errors;
  constexpr int kScans = 12;
  for (int k = 0; k < kScans; ++k) {
    const double start = 0.1 + k * kScanPeriod;
    rig.publishTfUntil(start + kScanPeriod + 0.02);
    const sim::SimulatedScan input = rig.publishScan(start);
    sensor_msgs::LaserScan::ConstPtr scan;
    sensor_msgs::PointCloud2::ConstPtr cloud;
    ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 5.0, scan, cloud)) << name << ": scan " << k;
    EXPECT_EQ(cloud->header.frame_id, TfTree::named(name).laser);  // the input's own frame id, as it was
    for (double d : cloudDistances(rig, *cloud))
      cloud_errors.push_back(d);
    for (double d : rawDistances(rig, input, start))
      raw_errors.push_back(d);
  }
  // tf's own interpolation between 50 Hz samples leaves under a millimetre on this arc; the raw scans
  // are decimetres off.
  const double cloud_rms = rms(cloud_errors), raw_rms = rms(raw_errors);
  std::printf("%s: cloud %.3f mm RMS, raw %.1f mm RMS\n", name.c_str(), 1e3 * cloud_rms, 1e3 * raw_rms);
  EXPECT_LT(cloud_rms, 2e-3) << name;
  EXPECT_GT(raw_rms, 20e-3) << name;
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("published") >= kScans; }, 5.0));
  EXPECT_EQ(rig.diagnosticNumber("dropped: tf"), 0.0);
  EXPECT_EQ(rig.diagnosticNumber("dropped: mount"), 0.0);
  EXPECT_EQ(rig.diagnosticNumber("statics ignored"), 0.0);  // no static link of these trees moves
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_trees");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
