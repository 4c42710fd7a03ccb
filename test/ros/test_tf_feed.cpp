// TfFeed, the one tf policy of node and bag tool, with a real tf2 buffer: what it keeps, what it leaves
// out, and what it answers, against the transforms fed (closed form).
#include <gtest/gtest.h>
#include <rosbag/view.h>
#include <tf2/exceptions.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <set>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/tf_feed.h"
#include "support/holds.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::TfEvent;
using ros_adapter::TfFeed;

struct Fed {
  explicit Fed(double cache_time = 10.0, const std::string& fixed = "odom",
               const std::string& base = "base_link")
      : feed(fixed, base, cache_time, [this](TfEvent event, const std::string& text) {
          ++events[event];
          texts[event] = text;
        }) {}
  std::map<TfEvent, int> events;
  std::map<TfEvent, std::string> texts;  // the last of each
  TfFeed feed;
};

core::TimeNs at(double t) {
  return Drive().epoch + core::secondsToNs(t);
}

const Drive kDrive;

/// The feed's newest chain time and its coverage of `time` [ns] (from the link's samples where they
/// hold it) against tf2's own: its latest common time (a lookup at 0) and canTransform.
void expectChainTimesAsTf2(const TfFeed& feed, core::TimeNs time, const std::string& what) {
  core::TimeNs newest = 0;
  try {
    newest = ros_adapter::toNs(
        feed.buffer().lookupTransform(feed.fixedFrame(), feed.baseFrame(), ros::Time(0)).header.stamp);
  } catch (const tf2::TransformException&) {
  }
  EXPECT_EQ(feed.newestChainTime(), newest) << what;
  EXPECT_EQ(feed.covers(time, time),
            feed.buffer().canTransform(feed.fixedFrame(), feed.baseFrame(), ros_adapter::toRosTime(time)))
      << what << " at " << time;
}

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

/// Expects `pose` (x, y, yaw) to be `truth` within 1e-9.
void expectPose(const std::optional<mrpt::poses::CPose3D>& pose, const sim::Pose2& truth, const char* what) {
  ASSERT_TRUE(pose) << what;
  EXPECT_NEAR(pose->x(), truth.x, 1e-9) << what;
  EXPECT_NEAR(pose->y(), truth.y, 1e-9) << what;
  EXPECT_NEAR(std::remainder(pose->yaw() - truth.yaw, 2 * M_PI), 0.0, 1e-9) << what;
}

// A mount re-published on /tf_static (a recalibration) holds from its stamp on: a sweep ending before
// it keeps the old one, whenever it is served. The first publication serves earlier sweeps too (a
// static stamped 0; a mount that came late), and one stamped 0 re-sent later replaces them all.
TEST(TfFeed, MountInForceAtTheSweepsEnd) {
  const sim::Pose2 old_mount{0.25, 0.05, 0.1}, new_mount{0.10, -0.20, 0.5}, zero_mount{-0.3, 0.1, -1.0};
  Fed fed;
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(0.0), old_mount), true);
  for (int k = 0; k <= 100; ++k)
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(1.0), new_mount), true);
  std::string error;
  expectPose(fed.feed.mount("laser", at(0.5), error), old_mount, "0.5 s");
  expectPose(fed.feed.mount("laser", at(1.0) - 1, error), old_mount, "1 ns before the change");
  expectPose(fed.feed.mount("laser", at(1.0), error), new_mount, "at the change");
  expectPose(fed.feed.mount("laser", at(1.5), error), new_mount, "1.5 s");
  expectPose(fed.feed.mount("laser", 0, error), new_mount, "the newest");
  expectPose(fed.feed.mount("laser", error), new_mount, "the newest");
  EXPECT_EQ(fed.events[TfEvent::kMountFirst], 1);
  EXPECT_EQ(fed.events[TfEvent::kMountChanged], 1);
  // tf2's own answer is the newest (what every sweep used to get).
  expectPose(
      ros_adapter::toPose(fed.feed.buffer().lookupTransform("base_link", "laser", ros::Time(0)).transform),
      new_mount, "tf2");
  // The same mount again, stamped later: nothing changes.
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(1.8), new_mount), true);
  expectPose(fed.feed.mount("laser", at(1.9), error), new_mount, "re-sent");
  EXPECT_EQ(fed.events[TfEvent::kMountChanged], 1);
  // Re-sent stamped 0 (unset): from the beginning, the later ones superseded.
  geometry_msgs::TransformStamped unset = stamped("base_link", "laser", kDrive.stampOf(0.0), zero_mount);
  unset.header.stamp = ros::Time(0);
  fed.feed.add(unset, true);
  expectPose(fed.feed.mount("laser", at(0.5), error), zero_mount, "stamped 0, at 0.5 s");
  expectPose(fed.feed.mount("laser", at(1.9), error), zero_mount, "stamped 0, at 1.9 s");

  // The first mount arriving stamped after a sweep serves it (the sweep waited for it).
  Fed late;
  late.feed.add(stamped("base_link", "laser", kDrive.stampOf(1.0), new_mount), true);
  expectPose(late.feed.mount("laser", at(0.5), error), new_mount, "late");
}

// The same rule through a chain: base_link -> plate changes at 1 s, plate -> laser stays; and with the
// base below the moving frame and the laser beside it (base_footprint -> base_link and
// base_footprint -> laser, both static), the laser's link changing at 1 s.
TEST(TfFeed, MountInForceThroughChains) {
  const sim::Pose2 plate_old{0.1, -0.05, 0.3}, plate_new{0.2, 0.05, -0.2}, laser_on_plate{0.15, 0.1, 0.2};
  Fed plate;
  plate.feed.add(stamped("base_link", "plate", kDrive.stampOf(0.0), plate_old), true);
  plate.feed.add(stamped("plate", "laser", kDrive.stampOf(0.0), laser_on_plate), true);
  plate.feed.add(stamped("base_link", "plate", kDrive.stampOf(1.0), plate_new), true);
  std::string error;
  expectPose(plate.feed.mount("laser", at(0.9), error), plate_old.compose(laser_on_plate), "plate, old");
  expectPose(plate.feed.mount("laser", at(1.1), error), plate_new.compose(laser_on_plate), "plate, new");

  const sim::Pose2 base_offset{0.05, 0.02, 0.1}, laser_old{0.3, 0.0, 0.0}, laser_new{0.3, 0.1, 0.4};
  Fed beside(10.0, "odom", "base_link");
  beside.feed.add(stamped("base_footprint", "base_link", kDrive.stampOf(0.0), base_offset), true);
  beside.feed.add(stamped("base_footprint", "laser", kDrive.stampOf(0.0), laser_old), true);
  beside.feed.add(stamped("base_footprint", "laser", kDrive.stampOf(1.0), laser_new), true);
  for (int k = 0; k <= 100; ++k)
    beside.feed.add(
        stamped("odom", "base_footprint", kDrive.stampOf(0.02 * k), kDrive.trajectory.pose(0.02 * k)), false);
  const auto in_base = [&](const sim::Pose2& laser) {
    const Eigen::Vector2d origin = base_offset.applyInverse({0.0, 0.0});
    return sim::Pose2{origin.x(), origin.y(), -base_offset.yaw}.compose(laser);
  };
  expectPose(beside.feed.mount("laser", at(0.9), error), in_base(laser_old), "beside, old");
  expectPose(beside.feed.mount("laser", at(1.1), error), in_base(laser_new), "beside, new");
}

// A mount on /tf (a moving joint) is time-stamped already: taken at the sweep's end, tf's newest when
// it has not reached that.
TEST(TfFeed, MountOnTfIsTakenAtTheSweepsEnd) {
  Fed fed;
  for (int k = 0; k <= 100; ++k)
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(0.0), {0.2, 0.0, 0.0}), false);
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(1.0), {0.4, 0.0, 0.0}), false);
  std::string error;
  expectPose(fed.feed.mount("laser", at(0.25), error), {0.25, 0.0, 0.0}, "between its samples");
  expectPose(fed.feed.mount("laser", at(1.5), error), {0.4, 0.0, 0.0}, "after its newest");
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
  // 4 s back (a bag loop), and the new time line goes on: a jump at the third transform in a row.
  EXPECT_TRUE(fed.feed.add(kDrive.motionAt(0.0), false));
  EXPECT_TRUE(fed.feed.jumpPending());
  EXPECT_TRUE(fed.feed.add(kDrive.motionAt(0.02), false));
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0);
  EXPECT_FALSE(fed.feed.add(kDrive.motionAt(0.04), false));
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
  EXPECT_FALSE(fed.feed.jumpPending());
  EXPECT_FALSE(fed.feed.covers(kDrive.epoch + core::secondsToNs(3.0), kDrive.epoch + core::secondsToNs(3.0)));
  // The three held transforms start the new time line.
  EXPECT_TRUE(fed.feed.covers(at(0.0), at(0.04)));
  EXPECT_EQ(fed.feed.newestChainTime(), at(0.04));
  for (const double t : {0.0, 0.03, 0.04, 0.05, 3.0, 4.0})
    expectChainTimesAsTf2(fed.feed, at(t), "after the jump");
  EXPECT_EQ(fed.events[TfEvent::kStaleIgnored], 0);
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
  for (const double t : {0.5, 0.52, 0.54})
    fed.feed.add(kDrive.motionAt(t), false);
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
}

// A stray second publisher of odom -> base_link, 3 s stale at 2 Hz, beside the real one at 50 Hz: its
// transforms go back, but the real time line goes on after each. They are left out (each reported),
// the cache is kept, and tf answers the true motion at their stamps (they carry a wrong pose here).
// Three transforms going back in a row afterwards are still a time jump.
TEST(TfFeed, StaleTfOfAStrayPublisherIsLeftOutAndTheCacheKept) {
  Fed fed;
  int stray = 0;
  for (int k = 0; k <= 500; ++k) {
    const double t = 0.02 * k;
    fed.feed.add(kDrive.motionAt(t), false);
    if (k % 25 == 0 && t >= 3.5) {
      fed.feed.add(stamped("odom", "base_link", kDrive.stampOf(t - 3.0), {100.0, -50.0, 2.0}), false);
      ++stray;
    }
  }
  fed.feed.add(kDrive.motionAt(10.02), false);  // the old time line goes on after the last one too
  EXPECT_EQ(stray, 14);
  EXPECT_EQ(fed.events[TfEvent::kStaleIgnored], stray);
  EXPECT_TRUE(
      holds(fed.texts[TfEvent::kStaleIgnored], "odom -> base_link stamped 3.02 s before the link's newest"));
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0);
  EXPECT_FALSE(fed.feed.jumpPending());
  EXPECT_TRUE(fed.feed.covers(at(1.0), at(10.0)));  // nothing cleared: 9 s of history
  for (const double t : {4.0, 5.5, 7.0}) {          // stray stamps
    const mrpt::poses::CPose3D pose = fed.feed.motion().basePose(at(t));
    EXPECT_NEAR(pose.x(), kDrive.trajectory.pose(t).x, 1e-9) << t;
    EXPECT_NEAR(std::remainder(pose.yaw() - kDrive.trajectory.pose(t).yaw, 2 * M_PI), 0.0, 1e-9) << t;
  }
  for (const double t : {0.0, 0.02, 0.04})
    fed.feed.add(kDrive.motionAt(t), false);
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
}

// A stray publisher of map -> odom (off the chain odom -> base_link) 60 s stale beside the real one:
// tf2 refused each of its transforms, older than its 10 s cache, with a TF_OLD_DATA warning on the
// console at every one. They are left out before tf2 sees them, counted as stale tf, and the real
// map -> odom is still answered.
TEST(TfFeed, TfOlderThanTheCacheIsLeftOutBeforeTf2) {
  Fed fed;
  for (int k = 0; k <= 1000; ++k) {
    const double t = 0.02 * k;
    fed.feed.add(kDrive.motionAt(t), false);
    fed.feed.add(stamped("map", "odom", kDrive.stampOf(t), {1.0, 2.0, 0.5}), false);
    if (k % 50 == 0 && t >= 1.0)
      fed.feed.add(stamped("map", "odom", kDrive.stampOf(t - 60.0), {9.0, 9.0, 1.0}), false);
  }
  EXPECT_EQ(fed.events[TfEvent::kStaleIgnored], 20);
  EXPECT_EQ(fed.events[TfEvent::kBadTransform], 0);  // tf2 refused them: 20, each warned on the console
  EXPECT_TRUE(
      holds(fed.texts[TfEvent::kStaleIgnored],
            "map -> odom stamped 60 s before the frame's newest, more than the tf cache keeps (10 s)"));
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0);
  const geometry_msgs::TransformStamped map_odom =
      fed.feed.buffer().lookupTransform("map", "odom", kDrive.stampOf(15.0));
  EXPECT_NEAR(map_odom.transform.translation.x, 1.0, 1e-9);
  EXPECT_TRUE(fed.feed.covers(at(11.0), at(20.0)));
}

// A transform tf2 refuses leaves no trace: one stamped near ros::Time's end (2106, tf2 throws on it)
// moved the link's newest stamp there, so every real transform after it went back 'by 80 years' and
// three in a row cleared the cache as a time jump.
TEST(TfFeed, RefusedTransformDoesNotMoveTheLinksNewestStamp) {
  Fed fed;
  for (int k = 0; k <= 50; ++k)
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  geometry_msgs::TransformStamped refused = kDrive.motionAt(1.0);
  refused.header.stamp =
      ros_adapter::toRosTime((core::TimeNs{1} << 32) * 1'000'000'000 - core::secondsToNs(5.0));
  EXPECT_TRUE(fed.feed.add(refused, false));
  EXPECT_EQ(fed.events[TfEvent::kBadTransform], 1);
  for (int k = 51; k <= 60; ++k)
    EXPECT_TRUE(fed.feed.add(kDrive.motionAt(0.02 * k), false)) << k;
  EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0);
  EXPECT_EQ(fed.events[TfEvent::kStaleIgnored], 0);
  EXPECT_FALSE(fed.feed.jumpPending());
  EXPECT_TRUE(fed.feed.covers(at(0.0), at(1.2)));  // nothing cleared
  EXPECT_EQ(fed.feed.newestChainTime(), at(1.2));
}

// A second publisher of odom -> base_link on another clock, told apart by the time line tf must serve
// (the scans' stamps, carried on by the owner's clock between scans): 3 s ahead at 2 Hz (it became
// the link's newest, and the real tf after it went back: a false jump at each of its messages), 3 s
// behind at 200 Hz (four in a row between two real ones: a false jump each time). Both are left out,
// counted by kind, the cache kept, tf answering the true motion. The clock decides before any scan.
// A real jump onto the scans' time line clears at once.
TEST(TfFeed, StrayOnAnotherClockIsToldApartByTheScansTimeLine) {
  for (const double offset : {3.0, -3.0}) {
    Fed fed;
    const int every = offset > 0.0 ? 100 : 1;  // of the 5 ms ticks: 2 Hz ahead, 200 Hz behind
    for (int i = 0; i <= 2000; ++i) {          // 10 s
      const double t = 0.005 * i;
      fed.feed.observeClock(at(t + 0.01));  // the clock (another: record time), 10 ms on
      if (i % 4 == 0)
        fed.feed.add(kDrive.motionAt(t), false);
      if (i % 5 == 0 && t >= 0.025)
        fed.feed.observeSweep(at(t));  // a scan that ended at t arrives
      if (i % every == 0 && t >= 0.5) {
        geometry_msgs::TransformStamped stray = kDrive.motionAt(t);
        stray.header.stamp = kDrive.stampOf(t + offset);
        fed.feed.add(stray, false);
      }
    }
    const TfEvent kind = offset > 0.0 ? TfEvent::kAheadIgnored : TfEvent::kStaleIgnored;
    EXPECT_EQ(fed.events[kind], offset > 0.0 ? 20 : 1901) << offset;
    EXPECT_EQ(fed.events[TfEvent::kTimeJump], 0) << offset;
    EXPECT_FALSE(fed.feed.jumpPending());
    EXPECT_EQ(fed.feed.newestChainTime(), at(10.0)) << offset;
    EXPECT_TRUE(fed.feed.covers(at(0.5), at(10.0))) << offset;  // nothing cleared
    for (const double t : {2.0, 5.5, 9.98}) {                   // at tf's samples
      const mrpt::poses::CPose3D pose = fed.feed.motion().basePose(at(t));
      EXPECT_NEAR(pose.x(), kDrive.trajectory.pose(t).x, 1e-9) << t;
    }
    EXPECT_TRUE(holds(fed.texts[kind], "3 s off the time line of the scans' stamps")) << fed.texts[kind];
    // A bag loop (the clock going on): the scans' stamps go back, and the next tf goes back with them: a
    // jump at once, the new time line served from that transform.
    fed.feed.observeClock(at(10.1));
    fed.feed.observeSweep(at(0.025));
    EXPECT_FALSE(fed.feed.add(kDrive.motionAt(0.04), false));
    EXPECT_EQ(fed.events[TfEvent::kTimeJump], 1);
    EXPECT_EQ(fed.feed.jumpedTo(), at(0.04));
    EXPECT_EQ(fed.feed.newestChainTime(), at(0.04));
  }
  // No scan yet: the owner's clock decides (a stray ahead is left out from its first message).
  Fed clock_only;
  for (int k = 0; k <= 100; ++k) {
    clock_only.feed.observeClock(at(0.02 * k));
    clock_only.feed.add(kDrive.motionAt(0.02 * k), false);
    if (k % 25 == 10) {
      geometry_msgs::TransformStamped stray = kDrive.motionAt(0.02 * k);
      stray.header.stamp = kDrive.stampOf(0.02 * k + 3.0);
      clock_only.feed.add(stray, false);
    }
  }
  EXPECT_EQ(clock_only.events[TfEvent::kAheadIgnored], 4);
  EXPECT_EQ(clock_only.events[TfEvent::kTimeJump], 0);
  EXPECT_TRUE(holds(clock_only.texts[TfEvent::kAheadIgnored], "off the time line of the clock"));
  // A clock on another time line (a bag's record time on the recorder's clock, far from the stamps)
  // tells nothing: the transforms' own rule (three in a row going back) decides.
  Fed far;
  for (int k = 0; k <= 100; ++k) {
    far.feed.observeClock(at(0.02 * k + 80.0));
    far.feed.add(kDrive.motionAt(0.02 * k), false);
  }
  for (const double t : {0.0, 0.02})
    far.feed.add(kDrive.motionAt(t), false);
  EXPECT_TRUE(far.feed.jumpPending());
  far.feed.add(kDrive.motionAt(0.04), false);
  EXPECT_EQ(far.events[TfEvent::kTimeJump], 1);
}

// Stamps tf can never cover are told apart from late tf, and never throw: an uninitialised stamp in
// 2105 (tf2 itself throws "Duration is out of dual 32-bit range" for it), 1970, both more than a day
// from tf's newest; a stamp an hour ahead is merely not covered yet. A transform stamped within the
// cache time of ros::Time's end (2106), which tf2 throws on when adding it, is refused and reported.
TEST(TfFeed, StampsTfCannotTakeAreNeverCovered) {
  Fed fed;
  for (int k = 0; k <= 50; ++k)
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  const core::TimeNs year_2105 = 4'260'211'200'000'000'000;
  std::string why;
  EXPECT_EQ(fed.feed.coverage(year_2105, year_2105 + 25'000'000, &why), ros_adapter::Coverage::kNever);
  EXPECT_TRUE(holds(why, "after tf's newest odom -> base_link")) << why;
  EXPECT_TRUE(holds(why, "uninitialised, or on another clock"));
  EXPECT_EQ(fed.feed.coverage(1'000'000'000, 1'025'000'000, &why), ros_adapter::Coverage::kNever);
  EXPECT_TRUE(holds(why, "before tf's newest"));
  EXPECT_EQ(fed.feed.coverage(at(3600.0), at(3600.025)), ros_adapter::Coverage::kNotYet);
  EXPECT_EQ(fed.feed.coverage(at(0.5), at(0.525)), ros_adapter::Coverage::kCovered);
  // tf2 itself throws on such a stamp: what TfFeed::coverage keeps it from.
  EXPECT_THROW(fed.feed.buffer().canTransform("odom", "base_link", ros_adapter::toRosTime(year_2105), &why),
               std::runtime_error);

  Fed end;
  const core::TimeNs near_end = (core::TimeNs{1} << 32) * 1'000'000'000 - core::secondsToNs(5.0);
  for (const core::TimeNs stamp : {near_end, near_end + 20'000'000}) {
    geometry_msgs::TransformStamped transform = kDrive.motionAt(0.0);
    transform.header.stamp = ros_adapter::toRosTime(stamp);
    EXPECT_NO_THROW(end.feed.add(transform, false));
  }
  EXPECT_EQ(end.events[TfEvent::kBadTransform], 2);
  EXPECT_TRUE(holds(end.texts[TfEvent::kBadTransform], "tf2 refused /tf odom -> base_link"));
  EXPECT_TRUE(holds(end.texts[TfEvent::kBadTransform], "Time is out of dual 32-bit range"));
}

// Why tf does not cover a sweep, by cause, naming the frames.
TEST(TfFeed, WhyNotCoveredNamesTheCause) {
  // fixed_frame misspelt: unknown to tf, with the closest frame tf knows.
  Fed typo(10.0, "odm");
  for (const auto& link : kDrive.statics())
    typo.feed.add(link, true);
  for (int k = 0; k <= 50; ++k)
    typo.feed.add(kDrive.motionAt(0.02 * k), false);
  EXPECT_EQ(typo.feed.whyNotCovered(at(0.5), at(0.525), at(0.53)),
            "fixed_frame 'odm' is unknown to tf (did you mean 'odom'?); tf's frames: base_link, laser, odom");
  // The scan's frame misspelt: the mount's cause.
  EXPECT_EQ(
      typo.feed.whyNoMount("lasr"),
      "the scan's frame 'lasr' is unknown to tf (did you mean 'laser'?); tf's frames: base_link, laser, "
      "odom");

  Fed fed;
  for (int k = 0; k <= 50; ++k)  // tf up to 1.0 s
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
  // tf short of the sweep's end [1.0, 1.1], which ended before the scan arrived (1.2): late tf.
  EXPECT_EQ(fed.feed.whyNotCovered(at(1.0), at(1.1), at(1.2)),
            "tf odom -> base_link has not reached the sweep's end: its newest is 100.0 ms before it");
  // The sweep ends 50 ms after it arrived: a driver stamping late.
  EXPECT_TRUE(holds(
      fed.feed.whyNotCovered(at(1.0), at(1.1), at(1.05)),
      "tf odom -> base_link ends 100.0 ms before the sweep's end, which lies 50.0 ms after the arrival"));
  // Every remedy offered: the offset (found by deskew_calibrate), or waiting longer.
  EXPECT_TRUE(holds(fed.feed.whyNotCovered(at(1.0), at(1.1), at(1.05)),
                    "Set time_offset (deskew_calibrate finds it from a recording), or give tf longer with a "
                    "longer tf_timeout"));
  // The mount's frame known but not connected to the base.
  fed.feed.add(stamped("plate", "laser", kDrive.stampOf(0.0), {}), true);
  EXPECT_TRUE(holds(fed.feed.whyNoMount("laser"), "not connected to base_link"));
  // A second parent of base_link on /tf (a localiser publishing map -> base_link): reported once, and
  // named as the cause.
  for (int k = 51; k <= 60; ++k) {
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
    fed.feed.add(stamped("map", "base_link", kDrive.stampOf(0.02 * k + 0.01), {1.0, 2.0, 0.3}), false);
  }
  EXPECT_EQ(fed.events[TfEvent::kTwoParents], 1);
  EXPECT_TRUE(holds(fed.texts[TfEvent::kTwoParents], "base_link has two parents on /tf, odom and map"));
  EXPECT_EQ(fed.feed.whyNotCovered(at(1.1), at(1.3), at(1.4)),
            "tf odom -> base_link: base_link has two parents on /tf, map and odom (two publishers of "
            "base_link?)");
  // fixed and base not connected at all.
  Fed apart(10.0, "odom", "base_link");
  apart.feed.add(stamped("odom", "x", kDrive.stampOf(0.0), {}), false);
  apart.feed.add(stamped("y", "base_link", kDrive.stampOf(0.0), {}), false);
  EXPECT_TRUE(holds(apart.feed.whyNotCovered(at(0.0), at(0.1), at(0.2)),
                    "tf odom -> base_link: the frames are not connected"));
}

// ---------------------------------------------------------------------------------------------------
// Poses without lookups: where fixed -> base crosses one dynamic link (statics around it), the motion
// source answers from the link's samples as they arrived, as tf2's own lookup answers, to the bit;
// elsewhere it asks tf2.

/// fixed -> base at `time` from the feed's motion source and from tf2's own lookup: the same bits, or
/// neither answers; the newest chain time and the coverage as tf2's too.
void expectAsTf2(const TfFeed& feed, core::TimeNs time, const std::string& what) {
  expectChainTimesAsTf2(feed, time, what);
  std::optional<mrpt::poses::CPose3D> ours, theirs;
  try {
    ours = feed.motion().basePose(time);
  } catch (const core::MotionUnavailable&) {
  }
  try {
    theirs = ros_adapter::toPose(
        feed.buffer()
            .lookupTransform(feed.fixedFrame(), feed.baseFrame(), ros_adapter::toRosTime(time))
            .transform);
  } catch (const tf2::TransformException&) {
  }
  ASSERT_EQ(ours.has_value(), theirs.has_value()) << what << " at " << time;
  if (!ours)
    return;
  const auto a = ours->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
  const auto b = theirs->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 4; ++column) {
      const double x = a(row, column), y = b(row, column);
      ASSERT_EQ(std::memcmp(&x, &y, sizeof x), 0)
          << what << " at " << time << " (" << row << ", " << column << "): " << x << " vs tf2's " << y;
    }
  }
  // The same bits as a rotation matrix and translation (the twist fit reads them so), where the chain
  // answers (elsewhere it asks tf2, as basePose did: the tests count those lookups).
  if (!feed.motion().chain().answers(time))
    return;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  feed.motion().baseTransform(time, rotation, translation);
  for (int row = 0; row < 3; ++row) {
    for (int column = 0; column < 4; ++column) {
      const double x = column < 3 ? rotation(row, column) : translation[row], y = b(row, column);
      ASSERT_EQ(std::memcmp(&x, &y, sizeof x), 0) << what << " at " << time << " (" << row << ", " << column
                                                  << "): baseTransform's " << x << " vs tf2's " << y;
    }
  }
}

/// parent -> child at t [s]: the drive's arc with a wobbling pitch, roll and height (all of the
/// quaternion's components move).
geometry_msgs::TransformStamped wobbling(const std::string& parent, const std::string& child, double t,
                                         double phase = 0.0) {
  const sim::Pose2 pose = kDrive.trajectory.pose(t);
  const mrpt::poses::CPose3D pose3 = mrpt::poses::CPose3D::FromXYZYawPitchRoll(
      pose.x + phase, pose.y, 0.1 * std::sin(3.0 * t), pose.yaw + phase, 0.05 * std::sin(5.0 * t + phase),
      0.08 * std::cos(4.0 * t));
  geometry_msgs::TransformStamped transform;
  transform.header.frame_id = parent;
  transform.child_frame_id = child;
  transform.header.stamp = kDrive.stampOf(t);
  transform.transform = ros_adapter::toTransform(pose3);
  return transform;
}

/// Times over [from, to] [s]: every 20 ms sample's stamp, 1 ns either side, and between samples (1 ns
/// outside the span at either end).
std::vector<core::TimeNs> queryTimes(double from, double to) {
  std::vector<core::TimeNs> times;
  for (core::TimeNs time = at(from); time <= at(to); time += 20'000'000) {
    for (const core::TimeNs offset : {-1L, 0L, 1L, 3'000'000L, 10'000'000L, 17'777'777L}) {
      if (time + offset <= at(to) + 1)
        times.push_back(time + offset);
    }
  }
  return times;
}

// One dynamic link with statics below and above it; the fixed frame a root, a static's child, or a
// localiser's (map -> odom on /tf at 10 Hz from 1.5 s to 2.5 s: tf2's walk ends there within those
// times only): every answer is tf2's, to the bit, at and between its samples and at the ends of what
// its cache keeps (2 s here), and none asks tf2.
TEST(TfFeed, OneDynamicLinkIsAnsweredAsTf2WithoutALookup) {
  struct Tree {
    const char* name;
    std::string fixed, base, moving_parent, moving;
    std::vector<geometry_msgs::TransformStamped> statics;
    bool localiser = false;  ///< map -> odom on /tf
  };
  const ros::Time t0 = kDrive.stampOf(0.0);
  const std::vector<Tree> trees = {
      {"direct", "odom", "base_link", "odom", "base_link", {}},
      {"static below (REP-105)",
       "odom",
       "base_link",
       "odom",
       "base_footprint",
       {stamped("base_footprint", "base_link", t0, {0.05, 0.02, 0.1})}},
      {"statics above and below, fixed a root",
       "map",
       "base_link",
       "odom",
       "base_footprint",
       {stamped("map", "world", t0, {3.0, -1.0, 0.7}), stamped("world", "odom", t0, {0.5, 0.2, -0.3}),
        stamped("base_footprint", "mid", t0, {0.1, 0.0, 0.2}),
        stamped("mid", "base_link", t0, {0.0, 0.3, 0.0})}},
      {"fixed under a static parent",
       "odom",
       "base_link",
       "odom",
       "base_link",
       {stamped("earth", "odom", t0, {10.0, 20.0, 1.0})}},
      {"fixed under a localiser", "odom", "base_link", "odom", "base_link", {}, true},
  };
  for (const Tree& tree : trees) {
    Fed fed(2.0, tree.fixed, tree.base);
    for (const auto& link : tree.statics)
      fed.feed.add(link, true);
    fed.feed.add(stamped(tree.base, "laser", t0, {0.25, 0.05, 0.1}), true);
    for (int k = 0; k <= 150; ++k) {
      fed.feed.add(wobbling(tree.moving_parent, tree.moving, 0.02 * k), false);
      if (tree.localiser && k % 5 == 0 && k >= 75 && k <= 125)
        fed.feed.add(wobbling("map", "odom", 0.02 * k, 0.7), false);
    }
    const std::size_t lookups = fed.feed.motion().tfLookups();
    // tf2 keeps 1.0 s to 3.0 s: its earliest and newest answered as they are, the rest interpolated.
    for (const core::TimeNs time : queryTimes(1.0, 3.0))
      expectAsTf2(fed.feed, time, tree.name);
    EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + 2) << tree.name;  // 1 ns outside, either end
    // Not a mock of tf2: the answers are the tree's poses.
    const sim::Pose2 moving = kDrive.trajectory.pose(2.0);
    if (tree.statics.empty() && !tree.localiser) {
      const mrpt::poses::CPose3D base = fed.feed.motion().basePose(at(2.0));
      EXPECT_NEAR(base.x(), moving.x, 1e-9);
      EXPECT_NEAR(base.y(), moving.y, 1e-9);
      EXPECT_NEAR(std::remainder(base.yaw() - moving.yaw, 2 * M_PI), 0.0, 1e-9);
    }
  }
}

// Two dynamic links on the chain (odom -> base_footprint -> base_link both on /tf): tf2 answers, as
// before.
TEST(TfFeed, TwoDynamicLinksAskTf2) {
  Fed fed(10.0, "odom", "base_link");
  for (int k = 0; k <= 100; ++k) {
    fed.feed.add(wobbling("odom", "base_footprint", 0.02 * k), false);
    fed.feed.add(wobbling("base_footprint", "base_link", 0.02 * k + 0.007, 0.3), false);
  }
  const std::vector<core::TimeNs> times = queryTimes(0.0, 2.0);
  for (const core::TimeNs time : times)
    expectAsTf2(fed.feed, time, "two dynamic links");
  EXPECT_EQ(fed.feed.motion().tfLookups(), times.size());
}

// The chain changes mid-stream: base_link's parent on /tf changes from odom to base_footprint (under a
// moving base_footprint: two dynamic links) at 1 s and back to odom at 2 s; the fixed frame then gains
// a static parent. tf2's cache of base_link holds samples of both parents; every answer is tf2's, and
// once the chain is one link again, the samples after its change are answered without tf2.
TEST(TfFeed, ChainChangingMidStreamIsAnsweredAsTf2) {
  Fed fed(10.0, "odom", "base_link");
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(0.0), {0.25, 0.05, 0.1}), true);
  const auto check = [&](double from, double to, const std::string& what) {
    for (const core::TimeNs time : queryTimes(from, to))
      expectAsTf2(fed.feed, time, what);
  };
  for (int k = 0; k < 50; ++k)
    fed.feed.add(wobbling("odom", "base_link", 0.02 * k), false);
  std::size_t lookups = fed.feed.motion().tfLookups();
  check(0.0, 0.98, "one link");
  EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + 2);  // 1 ns outside, either end
  for (int k = 50; k < 100; ++k) {
    fed.feed.add(wobbling("odom", "base_footprint", 0.02 * k + 0.005), false);
    fed.feed.add(wobbling("base_footprint", "base_link", 0.02 * k, 0.3), false);
  }
  check(0.0, 1.98, "two links");
  for (int k = 100; k <= 150; ++k)
    fed.feed.add(wobbling("odom", "base_link", 0.02 * k), false);
  check(0.0, 3.0, "one link again");
  lookups = fed.feed.motion().tfLookups();
  check(2.0, 3.0, "one link again");
  EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + 2);
  // odom under a static parent: tf2's walk ends at odom's own link now.
  fed.feed.add(stamped("earth", "odom", kDrive.stampOf(0.0), {10.0, 20.0, 1.0}), true);
  lookups = fed.feed.motion().tfLookups();
  check(2.0, 3.0, "odom under earth");
  EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + 2);
}

// Samples arriving out of order (one late, one repeated): tf2 takes the late one in between; answers
// stay tf2's, from tf2 itself around it, from the samples again after the next one in order.
TEST(TfFeed, OutOfOrderSamplesAreAnsweredAsTf2) {
  Fed fed;
  for (int k = 0; k <= 100; ++k) {
    if (k == 50)
      continue;
    fed.feed.add(wobbling("odom", "base_link", 0.02 * k), false);
    if (k == 52)
      fed.feed.add(wobbling("odom", "base_link", 1.0), false);  // 50 comes late
  }
  fed.feed.add(wobbling("odom", "base_link", 1.5), false);  // repeated: tf2 refuses it
  fed.feed.add(wobbling("odom", "base_link", 2.02), false);
  const std::size_t lookups = fed.feed.motion().tfLookups();
  const std::vector<core::TimeNs> times = queryTimes(0.0, 2.02);
  for (const core::TimeNs time : times)
    expectAsTf2(fed.feed, time, "out of order");
  // From tf2: before 1.06 s (the first sample in order after the late one), and after the newest.
  const auto asked = std::count_if(times.begin(), times.end(),
                                   [](core::TimeNs time) { return time < at(1.06) || time > at(2.02); });
  EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + static_cast<std::size_t>(asked));

  // With a 1 s cache: as tf2 forgets the samples up to the late one, the first sample kept becomes its
  // earliest (answered as it is, not interpolated), at 2.06 s and not before.
  Fed short_cache(1.0);
  for (int k = 0; k <= 110; ++k) {
    if (k != 50)
      short_cache.feed.add(wobbling("odom", "base_link", 0.02 * k), false);
    if (k == 52)
      short_cache.feed.add(wobbling("odom", "base_link", 1.0), false);
    if (k >= 100) {
      for (const core::TimeNs time : queryTimes(0.02 * k - 1.0, 0.02 * k - 0.9))
        expectAsTf2(short_cache.feed, time, "short cache at " + std::to_string(k));
    }
  }
}

// The twist fit over the feed's samples gives the points it gives over tf2's lookups, bit for bit, with
// no lookup.
TEST(TfFeed, TwistFitOverTheSamplesIsTheFitOverTf2) {
  Fed fed;
  ros_adapter::TfMotionSource through_tf2(fed.feed.buffer(), "odom", "base_link");
  through_tf2.setSingleLink(true);
  fed.feed.add(stamped("base_link", "laser", kDrive.stampOf(0.0), kDrive.mount), true);
  for (int k = 0; k <= 100; ++k) {
    fed.feed.add(kDrive.motionAt(0.02 * k), false);
    through_tf2.addSampleTime(ros_adapter::toNs(kDrive.stampOf(0.02 * k)));
  }
  core::ScanDeskewer ours, theirs;
  std::size_t points = 0;
  for (double start = 1.0; start < 1.9; start += 0.025) {
    const core::PlanarScan scan = ros_adapter::fromMsg(*kDrive.scanAt(start));
    const core::BeamTiming timing = core::resolveTiming(scan, {});
    core::DeskewedScan a, b;
    const mrpt::poses::CPose3D mount(kDrive.mount.x, kDrive.mount.y, 0.0, kDrive.mount.yaw, 0.0, 0.0);
    ours.deskew(scan, timing, mount, fed.feed.motion(), a);
    theirs.deskew(scan, timing, mount, through_tf2, b);
    ASSERT_EQ(a.points.size(), b.points.size());
    for (std::size_t i = 0; i < a.points.size(); ++i)
      ASSERT_EQ(a.points[i].position, b.points[i].position) << start << " s, point " << i;
    points += a.points.size();
  }
  EXPECT_GT(points, 10'000u);
  EXPECT_EQ(fed.feed.motion().tfLookups(), 0u);
  EXPECT_GT(through_tf2.tfLookups(), 50u);
}

// A real recording (the Neato's test drive: odom -> base_link on /tf, base_link's static parent left
// out): at and between every odometry sample, the answers are tf2's, to the bit, and none asks tf2.
TEST(TfFeed, RecordedOdometryIsAnsweredAsTf2WithoutALookup) {
  Fed fed(100.0);
  std::vector<core::TimeNs> stamps;
  rosbag::Bag bag = ros_adapter::openBagForReading(std::string(LIDAR_DESKEW_SOURCE_DIR) +
                                                   "/data/neato_xv11/test_drive.bag");
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{"/tf", "/tf_static"}))) {
    const auto transforms = message.instantiate<tf2_msgs::TFMessage>();
    ASSERT_TRUE(transforms);
    for (const geometry_msgs::TransformStamped& transform : transforms->transforms) {
      fed.feed.add(transform, message.getTopic() == "/tf_static");
      if (transform.child_frame_id == "base_link" && message.getTopic() == "/tf")
        stamps.push_back(ros_adapter::toNs(transform.header.stamp));
    }
  }
  ASSERT_GT(stamps.size(), 80u);
  std::sort(stamps.begin(), stamps.end());
  const std::size_t lookups = fed.feed.motion().tfLookups();
  std::size_t queries = 0;
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    for (const core::TimeNs offset : {-1L, 0L, 1L, 7'654'321L}) {
      expectAsTf2(fed.feed, stamps[k] + offset, "the Neato's odometry");
      ++queries;
    }
    if (k + 1 < stamps.size()) {
      expectAsTf2(fed.feed, (stamps[k] + stamps[k + 1]) / 2, "the Neato's odometry, between");
      ++queries;
    }
  }
  // tf2 is asked 1 ns before the first sample and after the last (7.7 ms included).
  EXPECT_EQ(fed.feed.motion().tfLookups(), lookups + 3);
  EXPECT_GT(queries, 400u);
}

// Sample times out of order and repeated, some older than the retention: kept are those within it of the
// newest, each once, in order, as a set of all times fed filtered so; the gaps are that set's.
TEST(TfMotionSource, SampleTimesAreTheRetainedSetOfAllFed) {
  tf2::BufferCore buffer;
  constexpr core::TimeNs kRetention = 1000;
  ros_adapter::TfMotionSource motion(buffer, "odom", "base_link", kRetention);
  std::mt19937_64 random(3);
  std::set<core::TimeNs> fed;
  core::TimeNs newest = 0;
  for (int k = 0; k < 3000; ++k) {
    const core::TimeNs time = 10 * k + static_cast<core::TimeNs>(random() % 400) - 200 + 5000;
    motion.addSampleTime(time);
    fed.insert(time);
    newest = std::max(newest, time);
    if (k == 0 || k % 97 != 0)
      continue;
    std::vector<core::TimeNs> kept;
    for (const core::TimeNs t : fed) {
      if (newest - t <= kRetention)
        kept.push_back(t);
    }
    std::vector<core::TimeNs> times;
    motion.appendSampleTimes(0, newest + 1, times);
    ASSERT_EQ(times, kept) << "after " << k;
    times.clear();
    motion.appendSampleTimes(kept[3], kept[9], times);  // strictly inside
    EXPECT_EQ(times, std::vector<core::TimeNs>(kept.begin() + 4, kept.begin() + 9));
    core::TimeNs gap = 0;
    for (std::size_t i = 2; i + 1 < kept.size() && kept[i] < kept[20]; ++i)
      gap = std::max(gap, kept[i + 1] - kept[i]);
    EXPECT_EQ(motion.longestGap(kept[2], kept[20]), gap);
  }
}

}  // namespace
}  // namespace lidar_deskew::test
