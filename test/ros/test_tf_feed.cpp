// TfFeed, the one tf policy of node and bag tool, with a real tf2 buffer: what it keeps, what it leaves
// out, and what it answers, against the transforms fed (closed form).
#include <gtest/gtest.h>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/tf_feed.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::TfEvent;
using ros_adapter::TfFeed;

struct Fed {
  explicit Fed(double cache_time = 10.0, const std::string& fixed = "odom",
               const std::string& base = "base_link")
      : feed(fixed, base, cache_time, [this](TfEvent event, const std::string&) { ++events[event]; }) {}
  std::map<TfEvent, int> events;
  TfFeed feed;
};

const Drive kDrive;

// Long recordings (deskew_bag reads the whole bag through one feed; the evaluation keeps a bag's
// whole tf): sample times are kept for the cache time, not a count, so knots and gaps are seen from
// the first second on. 100 s of 50 Hz tf is 5000 samples.
TEST(TfFeed, SampleTimesAreKeptForTheCacheTime) {
  Fed fed(200.0);
  for (int k = 0; k <= 5000; ++k) {
    const double t = 0.02 * k;
    if (t > 5.0 && t < 6.0)
      continue;  // a 1 s gap early on
    fed.feed.add(kDrive.motionAt(t), false);
  }
  const auto ns = [](double t) { return kDrive.epoch + core::secondsToNs(t); };
  std::vector<core::TimeNs> times;
  fed.feed.motion().appendSampleTimes(ns(0.0), ns(0.1), times);
  EXPECT_EQ(times.size(), 4u);  // 0.02, 0.04, 0.06, 0.08
  EXPECT_NEAR(core::nsToSeconds(fed.feed.motion().longestGap(ns(4.9), ns(6.1))), 1.0, 0.021);
  EXPECT_NEAR(core::nsToSeconds(fed.feed.motion().longestGap(ns(90.0), ns(91.0))), 0.02, 1e-6);
  EXPECT_TRUE(fed.feed.motion().sampleTimesComplete());  // one dynamic link straight from odom

  // With a 10 s cache only the last 10 s are kept, as tf2 keeps them.
  Fed short_cache(10.0);
  for (int k = 0; k <= 5000; ++k)
    short_cache.feed.add(kDrive.motionAt(0.02 * k), false);
  times.clear();
  short_cache.feed.motion().appendSampleTimes(ns(0.0), ns(100.0), times);
  EXPECT_EQ(times.size(), 500u);
}

// The motion answered is the fed trajectory composed with the static links below the moving frame.
TEST(TfFeed, MotionOfABaseBelowTheMovingFrame) {
  const TfTree tree = TfTree::named("rep105");
  Fed fed(10.0, tree.fixed, tree.base);
  for (const auto& link : staticLinks(tree, {0.25, 0.05, 0.1}, kDrive.stampOf(0.0)))
    fed.feed.add(link, true);
  for (int k = 0; k <= 10; ++k)
    fed.feed.add(stamped(tree.fixed, tree.moving, kDrive.stampOf(0.02 * k), kDrive.trajectory.pose(0.02 * k)),
                 false);
  const sim::Pose2 truth = kDrive.trajectory.pose(0.1).compose(tree.base_offset);
  const mrpt::poses::CPose3D base = fed.feed.motion().basePose(kDrive.epoch + core::secondsToNs(0.1));
  EXPECT_NEAR(base.x(), truth.x, 1e-9);
  EXPECT_NEAR(base.y(), truth.y, 1e-9);
  EXPECT_NEAR(base.yaw(), truth.yaw, 1e-9);
  EXPECT_FALSE(fed.feed.motion().sampleTimesComplete());  // a static link on the chain: knots between
  EXPECT_EQ(fed.events[TfEvent::kStaticIgnored], 0);
}

// Leading slashes (ROS 1's old tf style) are dropped everywhere, as tf2_ros's MessageFilter does.
TEST(TfFeed, LeadingSlashesAreNormalised) {
  const TfTree tree = TfTree::named("slash");
  Fed fed(10.0, "/odom", "base_link");
  for (const auto& link : staticLinks(tree, {0.25, 0.05, 0.1}, kDrive.stampOf(0.0)))
    fed.feed.add(link, true);
  fed.feed.add(stamped("/odom", "/base_link", kDrive.stampOf(0.0), kDrive.trajectory.pose(0.0)), false);
  fed.feed.add(stamped("/odom", "/base_link", kDrive.stampOf(0.1), kDrive.trajectory.pose(0.1)), false);
  EXPECT_EQ(fed.feed.fixedFrame(), "odom");
  EXPECT_TRUE(fed.feed.covers(kDrive.epoch, kDrive.epoch + 100'000'000));
  std::string error;
  const auto mount = fed.feed.mount("laser", error);
  ASSERT_TRUE(mount) << error;
  EXPECT_NEAR(mount->x(), 0.25, 1e-12);
  EXPECT_NEAR(mount->yaw(), 0.1, 1e-12);
}

// Time going back by more than 1 s on the chain clears the cache once; the mount is kept.
TEST(TfFeed, TimeJumpClearsTheCacheAndKeepsTheMount) {
  Fed fed;
  for (const auto& link : kDrive.statics())
    fed.feed.add(link, true);
  for (int k = 100; k <= 200; ++k)
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  std::string error;
  ASSERT_TRUE(fed.feed.mount("laser", error));
  EXPECT_TRUE(fed.feed.add(kDrive.motionAt(3.51), false));  // 0.49 s back: late, no jump
  EXPECT_FALSE(fed.feed.add(kDrive.motionAt(0.0), false));  // 4 s back: a bag loop
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
  EXPECT_FALSE(fed.feed.covers(kDrive.epoch + core::secondsToNs(3.0), kDrive.epoch + core::secondsToNs(3.0)));
  EXPECT_TRUE(fed.feed.mount("laser", error));
  // Transforms tf2 would refuse are reported, not thrown.
  EXPECT_TRUE(fed.feed.add(stamped("odom", "odom", kDrive.stampOf(0.1), {}), false));
  EXPECT_EQ(fed.events[TfEvent::kBadTransform], 1);
}

// Links of one chain may lead or lag each other by more than a second (AMCL future-dates map -> odom
// by its transform_tolerance): only a link going back against its own newest stamp is a time jump.
TEST(TfFeed, LinksThatLeadOthersAreNoTimeJump) {
  Fed fed(10.0, "map", "base_link");
  for (int k = 0; k <= 200; ++k) {
    const double t = 0.02 * k;
    fed.feed.add(kDrive.motionAt(t), false);
    fed.feed.add(stamped("map", "odom", kDrive.stampOf(t + 2.0), {1.0, 2.0, 0.3}), false);
  }
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0);
  EXPECT_TRUE(fed.feed.covers(kDrive.epoch + core::secondsToNs(3.0), kDrive.epoch + core::secondsToNs(3.5)));
  EXPECT_FALSE(fed.feed.motion().sampleTimesComplete());  // two moving links: knots between samples too
  // A real jump of one link is still one.
  fed.feed.add(kDrive.motionAt(0.5), false);
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
}

}  // namespace
}  // namespace lidar_deskew::test
