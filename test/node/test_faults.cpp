// Fault injection against the live node with a real roscore (docs/FAULTS.md). Each test states the expected
// behaviour and checks it, including the diagnostics counters.
#include <gtest/gtest.h>

#include <rosgraph_msgs/Log.h>
#include <std_msgs/UInt32.h>
#include <tf2_msgs/TFMessage.h>

#include <signal.h>
#include <sys/types.h>

#include <algorithm>
#include <cstdio>

#include "live_rig.h"
#include "support/holds.h"

namespace lidar_deskew::test {
namespace {

constexpr double kScanPeriod = 1.0 / 40.0;

/// Plays `count` scans from `start`, each with tf covering it first; returns how many outputs came.
/// `worst_rms` [m], when given, receives the largest RMS distance of a corrected cloud to the walls.
int playCovered(LiveRig& rig, double start, int count, double* worst_rms = nullptr) {
  int received = 0;
  for (int k = 0; k < count; ++k) {
    const double t = start + k * kScanPeriod;
    rig.publishTfUntil(t + kScanPeriod + 0.02);
    rig.publishScan(t);
    sensor_msgs::LaserScan::ConstPtr scan;
    sensor_msgs::PointCloud2::ConstPtr cloud;
    if (!rig.waitForOutputs(rig.stampOf(t), 5.0, scan, cloud))
      continue;
    ++received;
    if (worst_rms)
      *worst_rms = std::max(*worst_rms, rms(cloudDistances(rig, *cloud)));
  }
  return received;
}

/// Waits until the diagnostics report `key` at `value` (they come every 0.2 s).
bool diagnosticReaches(LiveRig& rig, const std::string& key, double value) {
  return rig.waitFor([&] { return rig.diagnosticNumber(key) == value; }, 5.0);
}

/// The value of the counter `key` in the first diagnostics this rig receives; -1 when none came in 5 s.
double counterNow(LiveRig& rig, const std::string& key) {
  rig.waitFor([&] { return !rig.diagnostic(key).empty(); }, 5.0);
  return rig.diagnosticNumber(key);
}

/// The node's `mount changes` after the scans served so far: from diagnostics published after them
/// (every 0.2 s); -1 when none came.
double changesSoFar(LiveRig& rig) {
  rig.spinFor(0.5);
  return rig.diagnosticNumber("mount changes");
}

// tf arrives late (after the scan, within tf_timeout): the scan waits and is then corrected.
TEST(Faults, LateTfIsWaitedFor) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 0.5;
  rig.publishTfUntil(start);
  rig.publishScan(start);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(start), 0.05, scan, cloud));  // waiting, not dropped
  rig.publishTfUntil(start + kScanPeriod + 0.02);                           // tf arrives 50 ms late
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(start), 5.0, scan, cloud));
  EXPECT_LT(rms(cloudDistances(rig, *cloud)), 2e-3);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("tf wait max [ms]") >= 40.0; }, 5.0))
      << rig.diagnostic("tf wait max [ms]");
}

// tf jumps back in time (a bag loop): one warning, the tf cache and the queue are cleared, the jump is
// counted, and scans of the new time line are corrected again.
TEST(Faults, TfJumpingBackClearsAndRecovers) {
  LiveRig later;
  ASSERT_TRUE(later.connect());
  ASSERT_EQ(playCovered(later, 20.0, 3), 3);  // stamps 20 s ahead of now
  LiveRig rig;                                // a new time line, starting now: 20 s back
  ASSERT_TRUE(rig.connect());
  EXPECT_EQ(playCovered(rig, 0.5, 3), 3);
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("time jumps") >= 1; }, 5.0));
}

// The same scan twice (a duplicate stamp): each is corrected and published; nothing is dropped.
TEST(Faults, DuplicateStampIsCorrectedTwice) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 40.0;
  rig.publishTfUntil(start + kScanPeriod + 0.02);
  rig.publishScan(start);
  rig.publishScan(start);
  EXPECT_TRUE(rig.waitFor([&] { return rig.outputCount(rig.stampOf(start), rig.stampOf(start)) == 2; }, 5.0));
  EXPECT_EQ(counterNow(rig, "dropped: invalid"), 0.0);
  EXPECT_EQ(counterNow(rig, "dropped: queue"), 0.0);
}

// Scans at 4x the sensor's rate (160 Hz of 1440 beams): all corrected, none dropped.
TEST(Faults, FourTimesTheRateIsServed) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double start = 60.0;
  const int count = 80;
  rig.publishTfUntil(start + count * kScanPeriod / 4 + kScanPeriod + 0.02);
  const ros::WallTime begin = ros::WallTime::now();
  for (int k = 0; k < count; ++k) {
    rig.publishScan(start + k * kScanPeriod / 4);
    ros::WallDuration(kScanPeriod / 4).sleep();
    ros::spinOnce();
  }
  const double elapsed = (ros::WallTime::now() - begin).toSec();
  const ros::Time first = rig.stampOf(start), last = rig.stampOf(start + (count - 1) * kScanPeriod / 4);
  EXPECT_TRUE(
      rig.waitFor([&] { return rig.outputCount(first, last) == static_cast<std::size_t>(count); }, 10.0))
      << rig.outputCount(first, last) << " of " << count;
  EXPECT_LT(elapsed, count * kScanPeriod / 4 * 2.0);  // the driver really published at about 160 Hz
  EXPECT_TRUE(rig.waitFor(
      [&] {
        return rig.diagnosticNumber("dropped: queue") == 0.0 && rig.diagnosticNumber("dropped: tf") == 0.0;
      },
      5.0));
}

// A tf gap mid-scan. Up to max_tf_gap (0.1 s here) tf2 interpolates across it and the scan is corrected:
// the chord replaces the arc, off by at most v·ω·h²/8. A longer gap is treated like missing tf: the
// scan is dropped (on_tf_failure: drop) and counted under "tf gaps"; the next covered scan is served.
TEST(Faults, TfGapMidScanIsBridgedUpToMaxTfGap) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double dropped_tf = counterNow(rig, "dropped: tf");
  ASSERT_GE(dropped_tf, 0.0) << "no diagnostics";
  // 80 ms without samples (79.98 -> 80.06) around the sweep [80.010, 80.035].
  rig.publishTfUntil(79.98);
  rig.skipTfUntil(80.04);
  rig.publishTfUntil(80.08);
  rig.publishScan(80.010);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(80.010), 5.0, scan, cloud));
  const double v = 6.0, w = 5.0, h = 0.08;  // the rig's arc, and the gap
  const double bridged = rms(cloudDistances(rig, *cloud));
  EXPECT_LT(bridged, v * w * h * h / 8.0) << "chord bound " << v * w * h * h / 8.0;
  std::printf("across an 80 ms tf gap: %.2f mm RMS (chord bound %.1f mm)\n", 1e3 * bridged,
              1e3 * v * w * h * h / 8.0);
  EXPECT_TRUE(diagnosticReaches(rig, "tf gaps", 0.0));

  // 200 ms without samples (81.00 -> 81.20) around the sweep [81.010, 81.035]: refused at once.
  rig.publishTfUntil(81.00);
  rig.skipTfUntil(81.18);
  rig.publishTfUntil(81.22);
  rig.publishScan(81.010);
  EXPECT_TRUE(diagnosticReaches(rig, "tf gaps", 1.0));
  EXPECT_TRUE(diagnosticReaches(rig, "dropped: tf", dropped_tf + 1.0));
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(81.010), 0.5, scan, cloud));
  double worst = 0.0;
  EXPECT_EQ(playCovered(rig, 81.25, 2, &worst), 2);  // tf is regular again
  EXPECT_LT(worst, 2e-3);
}

// Issue 24: a new mount stamped after a scan's sweep arrives while that scan waits for tf. The scan keeps
// the mount in force at its end (it got the new one: 40 mm RMS); the next scan, starting at the stamp,
// gets the new one. Before MountChangeAtRunTimeIsFollowed, which leaves the node with another mount than
// the next rig's until that rig's static arrives; this test's change is stamped 140 s ahead and serves
// none of the later tests' scans.
TEST(Faults, MountChangeServesTheScansEndingAfterItsStamp) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  double worst = 0.0;
  ASSERT_EQ(playCovered(rig, 140.0, 2, &worst), 2);
  EXPECT_LT(worst, 2e-3);
  const double changes = changesSoFar(rig);
  const sim::Pose2 old_mount = rig.mount;
  const double last_old = 140.05;  // its sweep ends 17 us before the next scan's first beam
  rig.publishTfUntil(last_old + 0.01);
  rig.publishScan(last_old);
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(last_old), 0.02, scan, cloud));  // waiting for tf
  rig.setMount({0.10, -0.20, 0.1 + 0.4}, last_old + kScanPeriod);  // at the next scan's first beam
  rig.spinFor(0.1);  // /tf_static and the scans come over different connections; tf_timeout is 0.3 s
  rig.publishTfUntil(last_old + kScanPeriod + 0.02);
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(last_old), 5.0, scan, cloud));
  const double old_error = rms(cloudDistances(rig, *cloud, old_mount));
  std::printf("the scan ending just before the change: %.3f mm RMS\n", 1e3 * old_error);
  EXPECT_LT(old_error, 2e-3);  // served with the new mount (before issue 24): 40 mm
  worst = 0.0;
  EXPECT_EQ(playCovered(rig, last_old + kScanPeriod, 2, &worst), 2);
  EXPECT_LT(worst, 2e-3);
  EXPECT_TRUE(diagnosticReaches(rig, "mount changes", changes + 1.0));
}

// The mount changes at run time (/tf_static re-published, as after a recalibration): scans are
// corrected with the new mount from then on, and the change is logged and counted. A re-published
// but equal mount is not a change.
TEST(Faults, MountChangeAtRunTimeIsFollowed) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  double worst = 0.0;
  ASSERT_EQ(playCovered(rig, 100.0, 2, &worst), 2);
  EXPECT_LT(worst, 2e-3);
  const double changes = changesSoFar(rig);  // the earlier tests' too
  rig.setMount(rig.mount);                   // the same again
  rig.setMount({0.10, -0.20, 0.1 + 0.4});    // moved 0.26 m and turned 0.4 rad: the old one is metres off
  ros::WallDuration(0.2).sleep();            // /tf_static and the scans come over different connections
  worst = 0.0;
  EXPECT_EQ(playCovered(rig, 100.1, 3, &worst), 3);
  EXPECT_LT(worst, 2e-3);
  EXPECT_TRUE(diagnosticReaches(rig, "mount changes", changes + 1.0));
}

// A scan whose mount (base_link -> its frame) is unknown waits for it: a mount that comes late is used;
// one that never comes drops the scan after tf_timeout, counted as "dropped: mount".
TEST(Faults, MissingMountIsWaitedForThenDropped) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double dropped_mount = counterNow(rig, "dropped: mount");
  ASSERT_GE(dropped_mount, 0.0) << "no diagnostics";
  const auto in = [](const std::string& frame) {
    return [frame](sensor_msgs::LaserScan& scan) { scan.header.frame_id = frame; };
  };
  rig.publishTfUntil(120.1);
  rig.publishScan(120.0, in("laser_never"));
  rig.publishScan(120.025, in("laser_late"));
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(120.025), 0.1, scan, cloud));  // waiting for its mount
  rig.publishStatic("base_link", "laser_late", rig.mount);  // the laser's true mount, under another name
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(120.025), 5.0, scan, cloud));
  EXPECT_LT(rms(cloudDistances(rig, *cloud)), 2e-3);
  EXPECT_TRUE(diagnosticReaches(rig, "dropped: mount", dropped_mount + 1.0));
  EXPECT_FALSE(rig.waitForOutputs(rig.stampOf(120.0), 0.1, scan, cloud));
  // The cause is on /diagnostics too, with both frames.
  EXPECT_TRUE(
      holds(rig.diagnostic("last drop"),
            "no transform base_link -> laser_never (the laser mount): the scan's frame 'laser_never' is "
            "unknown to tf"));
}

// Stamps tf cannot take between good scans: 2105 (uninitialised; tf2 threw inside the deskew and the
// scan jammed the queue's head, output stopped) and 0 (unset; it was counted as late tf). Each is
// dropped as invalid at once and named; every good scan is corrected, none blamed on tf.
TEST(Faults, BadStampsCostNoScan) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double dropped_invalid = counterNow(rig, "dropped: invalid");
  const double dropped_tf = counterNow(rig, "dropped: tf");
  ASSERT_GE(dropped_invalid, 0.0) << "no diagnostics";
  const double start = 121.0;
  rig.publishTfUntil(start);
  const auto stampedAt = [](const ros::Time& stamp) {
    return [stamp](sensor_msgs::LaserScan& scan) { scan.header.stamp = stamp; };
  };
  rig.publishScan(start, stampedAt(ros::Time(4'260'211'200, 0)));  // 2105
  rig.publishScan(start, stampedAt(ros::Time(0, 0)));
  double worst = 0.0;
  EXPECT_EQ(playCovered(rig, start, 8, &worst), 8);
  EXPECT_LT(worst, 2e-3);
  EXPECT_TRUE(diagnosticReaches(rig, "dropped: invalid", dropped_invalid + 2.0));
  EXPECT_EQ(rig.diagnosticNumber("dropped: tf"), dropped_tf);
  EXPECT_TRUE(holds(rig.diagnostic("last drop"), "invalid stamp: header.stamp is 0 (unset"));
}

// A stray second publisher of odom -> base_link, 3 s stale at 2 Hz, beside the real one at 50 Hz (it
// cleared the tf cache at each of its messages: 114 of 139 scans delivered). Its transforms are left
// out and counted, the cache kept: every scan is corrected, no time jump.
TEST(Faults, StaleTfOfAStrayPublisherCostsNoScan) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  ros::NodeHandle nh;
  ros::Publisher stray = nh.advertise<tf2_msgs::TFMessage>("/tf", 10);
  ASSERT_TRUE(rig.waitFor([&] { return stray.getNumSubscribers() > 0; }, 5.0));
  const double time_jumps = counterNow(rig, "time jumps");
  const double stale = counterNow(rig, "stale tf ignored");
  ASSERT_GE(time_jumps, 0.0) << "no diagnostics";
  const double start = 123.0;
  const int count = 80;  // 2 s at 40 Hz
  int delivered = 0;
  for (int k = 0; k < count; ++k) {
    const double t = start + k * kScanPeriod;
    if (k % 20 == 10) {
      tf2_msgs::TFMessage message;
      message.transforms.push_back(stamped("odom", "base_link", rig.stampOf(t - 3.0), {9.0, 9.0, 1.0}));
      stray.publish(message);
    }
    delivered += playCovered(rig, t, 1);
  }
  EXPECT_EQ(delivered, count);
  EXPECT_TRUE(diagnosticReaches(rig, "stale tf ignored", stale + 4.0));
  EXPECT_EQ(rig.diagnosticNumber("time jumps"), time_jumps);
}

// A second publisher of odom -> base_link on a clock 3 s ahead, at every scan (each became the link's
// newest and the real tf after it passed for a time jump: 0 of 739 scans in 20 s in the run,
// with 381 unthrottled "time went backwards" warnings). Told apart by the scans' stamps: left out,
// counted, said once; every scan corrected, no time jump, no warning per transform.
TEST(Faults, TfAheadOnAnotherClockIsNoTimeJumpAndSaidOnce) {
  std::size_t ahead_lines = 0, jump_lines = 0;
  ros::NodeHandle nh;
  const ros::Subscriber log =
      nh.subscribe<rosgraph_msgs::Log>("/rosout", 1000, [&](const rosgraph_msgs::Log::ConstPtr& line) {
        if (line->name != "/lidar_deskew")
          return;
        ahead_lines += line->msg.find("tf ahead") != std::string::npos;
        jump_lines += line->msg.find("time went backwards") != std::string::npos;
      });
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  ros::Publisher stray = nh.advertise<tf2_msgs::TFMessage>("/tf", 10);
  ASSERT_TRUE(rig.waitFor([&] { return stray.getNumSubscribers() > 0; }, 5.0));
  const double time_jumps = counterNow(rig, "time jumps");
  const double ahead = counterNow(rig, "tf ahead ignored");
  ASSERT_GE(time_jumps, 0.0) << "no diagnostics";
  const double start = 160.0;
  const int count = 80;  // 2 s at 40 Hz
  int delivered = 0;
  for (int k = 0; k < count; ++k) {
    const double t = start + k * kScanPeriod;
    tf2_msgs::TFMessage message;
    message.transforms.push_back(stamped("odom", "base_link", rig.stampOf(t + 3.0), {9.0, 9.0, 1.0}));
    stray.publish(message);
    delivered += playCovered(rig, t, 1);
  }
  EXPECT_EQ(delivered, count);
  // Each stray one counted (and the rig's own tf of this new time line, published before its first scan:
  // left out until that scan moved the time line onto it, then taken back).
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("tf ahead ignored") >= ahead + count; }, 5.0));
  EXPECT_EQ(rig.diagnosticNumber("time jumps"), time_jumps);
  rig.spinFor(0.5);  // the log's last lines
  EXPECT_LE(ahead_lines, 1u);
  EXPECT_EQ(jump_lines, 0u);
}

// The status is named once after the node ("lidar_deskew: deskew"; it read "lidar_deskew: /lidar_deskew:
// deskew"), and its message names the cause when sweeps are dropped.
TEST(Faults, StatusCarriesTheNodesNameOnce) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  ASSERT_TRUE(rig.waitFor([&] { return !rig.statusNames().empty(); }, 5.0));
  const std::vector<std::string> names = rig.statusNames();  // and "lidar_deskew: timing" once turned
  EXPECT_NE(std::find(names.begin(), names.end(), "lidar_deskew: deskew"), names.end());
  for (const std::string& name : names)
    EXPECT_EQ(name.find('/'), std::string::npos) << name;
  rig.publishTfUntil(126.1);
  rig.publishScan(126.0, [](sensor_msgs::LaserScan& scan) { scan.header.frame_id = "lasr"; });
  int level = -1;
  std::string message;
  EXPECT_TRUE(rig.waitFor(
      [&] {
        return rig.status(": deskew", level, message) &&
               message.find("the scan's frame 'lasr' is unknown to tf (did you mean 'laser'?)") !=
                   std::string::npos;
      },
      5.0))
      << message;
  EXPECT_EQ(level, diagnostic_msgs::DiagnosticStatus::WARN);
}

// A misspelt fixed_frame (misspelt_frame.test runs this alone, with fixed_frame 'odm'): every scan is
// dropped; once input stops, /diagnostics stays a WARN that nothing was corrected, naming the cause
// (it went back to "ok" at the first quiet period).
TEST(MisspeltFrame, NothingCorrectedStaysAWarning) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  int scans = 0;
  for (double t = 10.0; t < 10.5; t += 0.025, ++scans) {
    rig.publishTfUntil(t + 0.05);
    rig.publishScan(t);
    rig.spinFor(0.025);
  }
  ASSERT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("dropped: tf") >= scans; }, 5.0));
  rig.spinFor(1.0);  // quiet periods of 0.2 s: the input has stopped
  int level = -1;
  std::string message;
  ASSERT_TRUE(rig.status(": deskew", level, message));
  EXPECT_EQ(level, diagnostic_msgs::DiagnosticStatus::WARN) << message;
  EXPECT_TRUE(holds(message, "none of the " + std::to_string(scans) + " scans received was corrected; last drop:"))
      << message;
  EXPECT_TRUE(holds(message, "fixed_frame 'odm' is unknown to tf (did you mean 'odom'?)")) << message;
  EXPECT_EQ(rig.diagnosticNumber("input rate [Hz]"), 0.0);
}

// More scans wait for tf than queue_size (10): the oldest are dropped and counted as "dropped: queue";
// the newest 10 are corrected once tf comes.
TEST(Faults, QueueOverflowDropsTheOldest) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double dropped_queue = counterNow(rig, "dropped: queue");
  ASSERT_GE(dropped_queue, 0.0) << "no diagnostics";
  const double start = 130.0;
  rig.publishTfUntil(start);
  for (int k = 0; k < 15; ++k) {  // within 0.1 s, well inside tf_timeout
    rig.publishScan(start + k * kScanPeriod);
    rig.spinFor(0.005);
  }
  rig.publishTfUntil(start + 16 * kScanPeriod);
  const ros::Time first = rig.stampOf(start), last = rig.stampOf(start + 14 * kScanPeriod);
  EXPECT_TRUE(rig.waitFor([&] { return rig.outputCount(first, last) == 10; }, 5.0))
      << rig.outputCount(first, last);
  EXPECT_EQ(rig.outputCount(first, rig.stampOf(start + 4 * kScanPeriod)), 0u);
  EXPECT_TRUE(diagnosticReaches(rig, "dropped: queue", dropped_queue + 5.0));
}

// A /tf_static parent for the moving base (a common URDF slip) would make tf answer one pose for every
// time: it is ignored, with a warning, and scans stay corrected.
TEST(Faults, StaticParentOfTheBaseIsIgnored) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  rig.publishStatic("map", "base_link", {1.0, 2.0, 0.5});
  ros::WallDuration(0.2).sleep();
  double worst = 0.0;
  EXPECT_EQ(playCovered(rig, 135.0, 3, &worst), 3);
  EXPECT_LT(worst, 2e-3);
}

/// The pid of the deskew node launched by faults.test (0 when not found).
pid_t deskewPid() {
  FILE* pgrep = popen("pgrep -f '[_]_name:=lidar_deskew'", "r");  // [_]: not this shell itself
  int pid = 0;
  if (pgrep) {
    if (std::fscanf(pgrep, "%d", &pid) != 1)
      pid = 0;
    pclose(pgrep);
  }
  return pid;
}

// The deskew itself stalls (SIGSTOP for 0.5 s, longer than tf_timeout: descheduled by an overloaded
// host, swapped out) while the tf its waiting scan needs arrives. After the stall that tf is read and
// the scan corrected: the node's own stall is not taken for tf being late.
TEST(Faults, OwnStallIsNotTakenForLateTf) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const pid_t pid = deskewPid();
  ASSERT_GT(pid, 0);
  const double dropped_tf = counterNow(rig, "dropped: tf");
  ASSERT_GE(dropped_tf, 0.0) << "no diagnostics";
  for (int k = 0; k < 5; ++k) {
    const double t = 150.0 + 0.1 * k;
    rig.publishTfUntil(t);
    rig.publishScan(t);
    rig.spinFor(0.05);  // the scan is read and waits for tf
    ASSERT_EQ(kill(pid, SIGSTOP), 0);
    rig.publishTfUntil(t + kScanPeriod + 0.02);
    ros::WallDuration(0.5).sleep();
    ASSERT_EQ(kill(pid, SIGCONT), 0);
    sensor_msgs::LaserScan::ConstPtr scan;
    sensor_msgs::PointCloud2::ConstPtr cloud;
    EXPECT_TRUE(rig.waitForOutputs(rig.stampOf(t), 5.0, scan, cloud)) << "stall " << k;
  }
  EXPECT_TRUE(diagnosticReaches(rig, "dropped: tf", dropped_tf));
}

// A subscriber that takes 0.5 s per message (its socket fills up): every scan still reaches the other
// subscribers, nothing is dropped, and the slow one only gets what it can take. Runs last: the slow
// subscriber has been connected since the start.
TEST(Faults, SlowSubscriberDoesNotHoldOthersBack) {
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  ros::NodeHandle nh;
  int slow = -1;
  const ros::Subscriber slow_count = nh.subscribe<std_msgs::UInt32>(
      "/slow_subscriber/received", 10, [&](const std_msgs::UInt32::ConstPtr& count) { slow = count->data; });
  ASSERT_TRUE(rig.waitFor([&] { return slow >= 0; }, 10.0)) << "the slow subscriber never got a message";
  const int slow_before = slow;
  const double dropped_tf = counterNow(rig, "dropped: tf");
  ASSERT_GE(dropped_tf, 0.0) << "no diagnostics";
  const double dropped_queue = counterNow(rig, "dropped: queue");

  const double start = 140.0;
  const int count = 120;  // 3 s at 40 Hz
  for (int k = 0; k < count; ++k) {
    const double t = start + k * kScanPeriod;
    rig.publishTfUntil(t + kScanPeriod + 0.02);
    rig.publishScan(t);
    rig.spinFor(kScanPeriod);  // until the next scan
  }
  const ros::Time first = rig.stampOf(start), last = rig.stampOf(start + (count - 1) * kScanPeriod);
  EXPECT_TRUE(
      rig.waitFor([&] { return rig.outputCount(first, last) == static_cast<std::size_t>(count); }, 5.0))
      << rig.outputCount(first, last) << " of " << count;
  EXPECT_EQ(rig.diagnosticNumber("dropped: tf"), dropped_tf);
  EXPECT_EQ(rig.diagnosticNumber("dropped: queue"), dropped_queue);
  EXPECT_LT(slow - slow_before, count / 4) << "the slow subscriber was not slow";
  std::printf("slow subscriber took %d messages while the others got %d scans and %d clouds\n",
              slow - slow_before, count, count);
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_faults");
  return RUN_ALL_TESTS();
}
