// ScanPipeline, the one path of the live node and deskew_bag, fed by hand: real tf2 buffers, real
// messages, the simulator's truth. The robot drives a 6 m/s, 5 rad/s arc; tf at 50 Hz; UTM-30LX scans.
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "lidar_deskew/ros/scan_pipeline.h"
#include "lidar_deskew/ros/text_params.h"
#include "lidar_deskew/sim/sim.h"
#include "support/holds.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::PipelineCounters;
using ros_adapter::PipelineEvent;
using ros_adapter::PipelineResult;
using ros_adapter::ScanPipeline;

constexpr double kTfPeriod = 0.02;

/// A pipeline and everything it handed out.
struct PipelineRun {
  /// `fixed_frame`: instead of the tree's (a misspelt one).
  explicit PipelineRun(const Drive& drive_in, ros_adapter::DeskewParams params = {},
                       const std::string& fixed_frame = "",
                       ros_adapter::Waiting waiting = ros_adapter::Waiting::kTimeout,
                       const std::string& base_frame = "")
      : drive(drive_in),
        pipeline(
            withFrames(params, drive_in.tree, fixed_frame, base_frame),
            [this](const PipelineResult& result) { results.push_back(result); },
            [this](PipelineEvent event, const std::string& text) { events.emplace_back(event, text); }, 10.0,
            waiting) {}

  static ros_adapter::DeskewParams withFrames(ros_adapter::DeskewParams params, const TfTree& tree,
                                              const std::string& fixed_frame, const std::string& base_frame) {
    params.fixed_frame = fixed_frame.empty() ? tree.fixed : fixed_frame;
    params.base_frame = base_frame.empty() ? tree.base : base_frame;
    return params;
  }
  void statics(double now) { pipeline.addTransforms(drive.statics(), true, now); }
  /// tf samples every 20 ms after the last one fed, up to t [s].
  void tfUntil(double t) {
    for (; tf_until + kTfPeriod <= t + 1e-9; tf_until += kTfPeriod)
      pipeline.addTransforms({drive.motionAt(tf_until + kTfPeriod)}, false, tf_until + kTfPeriod);
  }
  /// One scan starting at t, then tf up to its end: returns its truth distances (empty when no output).
  void scan(double t) {
    pipeline.add(drive.scanAt(t), t + 1.0 / drive.model.rate);
    tfUntil(t + 1.0 / drive.model.rate + kTfPeriod);
  }
  /// Distances of every corrected point handed out so far to the true walls [m].
  std::vector<double> cloudDistances() const {
    std::vector<double> all;
    for (const PipelineResult& result : results) {
      if (!result.corrected)
        continue;
      for (double d : drive.distances(result.outputs.cloud->points, result.outputs.scan->header.stamp))
        all.push_back(d);
    }
    return all;
  }
  bool said(PipelineEvent event) const {
    return std::any_of(events.begin(), events.end(), [&](const auto& e) { return e.first == event; });
  }

  Drive drive;
  double tf_until = -0.1;
  std::vector<PipelineResult> results;
  std::vector<std::pair<PipelineEvent, std::string>> events;
  ScanPipeline pipeline;
};

// Trees as robots have them: the same accuracy whatever links stand between the fixed frame and the
// laser (statics before the motion, as a latched /tf_static arrives).
TEST(ScanPipeline, OrdinaryTreesAreCorrectedOntoTheTrueWalls) {
  for (const std::string name : {"default", "rep105", "plate", "base", "slash"}) {
    PipelineRun run{Drive(TfTree::named(name))};
    run.statics(0.0);
    run.tfUntil(0.05);
    for (int k = 0; k < 12; ++k)
      run.scan(0.1 + k * 0.025);
    const PipelineCounters& counters = run.pipeline.counters();
    EXPECT_EQ(counters.published, 12u) << name;
    EXPECT_EQ(counters.statics_ignored, 0u) << name;
    const double error = rms(run.cloudDistances());
    std::printf("%-8s cloud %.3f mm RMS over %zu scans\n", name.c_str(), 1e3 * error, run.results.size());
    EXPECT_LT(error, 1e-3) << name;  // tf's own interpolation between 50 Hz samples on this arc
    // The outputs keep the input's frame id as it was (a leading slash included).
    ASSERT_FALSE(run.results.empty());
    EXPECT_EQ(run.results.front().outputs.scan->header.frame_id, run.drive.tree.laser);
  }
}

// REP-105 with the static link arriving after the motion has started: kept (base_link does not move).
TEST(ScanPipeline, StaticBelowTheMovingFrameCountsWheneverItComes) {
  PipelineRun run{Drive(TfTree::named("rep105"))};
  run.tfUntil(0.05);
  run.statics(0.05);
  for (int k = 0; k < 8; ++k)
    run.scan(0.1 + k * 0.025);
  EXPECT_EQ(run.pipeline.counters().published, 8u);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
}

// A /tf_static parent of a frame that moves on /tf (a URDF's base_footprint -> base_link beside
// odom -> base_link) would freeze tf's answer: it is left out and said once, whichever came first.
TEST(ScanPipeline, StaticParentOfAMovingFrameIsLeftOutWhicheverCameFirst) {
  for (const bool static_first : {true, false}) {
    PipelineRun run{Drive()};
    const auto frozen = stamped("base_footprint", "base_link", run.drive.stampOf(0.0), {0.5, 0.5, 1.0});
    run.statics(0.0);
    if (static_first)
      run.pipeline.addTransforms({frozen}, true, 0.0);
    run.tfUntil(0.05);
    if (!static_first)
      run.pipeline.addTransforms({frozen}, true, 0.05);
    for (int k = 0; k < 8; ++k)
      run.scan(0.1 + k * 0.025);
    EXPECT_EQ(run.pipeline.counters().statics_ignored, 1u) << static_first;
    EXPECT_TRUE(run.said(PipelineEvent::kStaticIgnored));
    EXPECT_EQ(run.pipeline.counters().published, 8u) << static_first;
    EXPECT_LT(rms(run.cloudDistances()), 1e-3) << static_first;
  }
}

// A recalibration: /tf_static re-published with a new mount mid-stream serves the scans after it.
TEST(ScanPipeline, RepublishedMountServesTheScansAfterIt) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(0.05);
  for (int k = 0; k < 6; ++k)
    run.scan(0.1 + k * 0.025);
  const std::vector<double> before = run.cloudDistances();
  run.results.clear();
  run.drive.mount = {0.10, -0.20, 0.5};  // moved 0.26 m and turned 0.4 rad
  run.statics(0.25);
  for (int k = 6; k < 12; ++k)
    run.scan(0.1 + k * 0.025);
  EXPECT_EQ(run.pipeline.counters().published, 12u);
  EXPECT_EQ(run.pipeline.counters().mount_changes, 1u);
  EXPECT_LT(rms(before), 1e-3);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);  // with the old mount: decimetres
}

// The case: a scan waits for tf, and meanwhile /tf_static arrives with a new mount stamped after
// that scan's sweep (at the next scan's first beam). The waiting scan keeps the mount in force at its
// end; the scans after the stamp get the new one.
TEST(ScanPipeline, RepublishedMountServesTheScansEndingAfterItsStamp) {
  PipelineRun run{Drive()};
  const Drive old_drive = run.drive;  // the truth of the scans before the change
  run.statics(0.0);
  run.tfUntil(0.05);
  for (int k = 0; k < 4; ++k)
    run.scan(0.1 + k * 0.025);
  const double waiting = 0.2;  // its sweep ends 0.02 ms before the next scan's first beam
  run.pipeline.add(run.drive.scanAt(waiting), waiting + 0.025);
  EXPECT_EQ(run.pipeline.waiting(), 1u);  // tf ends at 0.22
  run.drive.mount = {0.10, -0.20, 0.5};   // moved 0.26 m and turned 0.4 rad
  run.pipeline.addTransforms(staticLinks(run.drive.tree, run.drive.mount, run.drive.stampOf(waiting + 0.025)),
                             true, waiting + 0.026);
  run.tfUntil(waiting + 0.05);
  for (int k = 5; k < 8; ++k)
    run.scan(0.1 + k * 0.025);
  ASSERT_EQ(run.results.size(), 8u);
  EXPECT_EQ(run.pipeline.counters().mount_changes, 1u);
  for (std::size_t k = 0; k < run.results.size(); ++k) {
    const PipelineResult& result = run.results[k];
    const Drive& truth = k < 5 ? old_drive : run.drive;
    const double error =
        rms(truth.distances(result.outputs.cloud->points, result.outputs.scan->header.stamp));
    if (k == 4 || k == 5)
      std::printf("scan %zu (%s mount): %.3f mm RMS\n", k, k < 5 ? "old" : "new", 1e3 * error);
    EXPECT_LT(error, 1e-3) << k;  // the waiting scan with the new mount: 32 mm
  }
}

// Live with a look-ahead of the twist fit (fit_look_ahead): a scan tf covers waits until tf passes its
// end by the look-ahead, and at tf_timeout it is served with what there is, not failed.
TEST(ScanPipeline, LiveScanWaitsForTheLookAheadThenIsServedWithWhatThereIs) {
  ros_adapter::DeskewParams params;
  params.tf_timeout = 0.3;
  params.deskew.fit_look_ahead = 0.1;
  PipelineRun run(Drive(), params);
  const double period = 1.0 / run.drive.model.rate;
  run.statics(0.0);
  run.tfUntil(0.2 + period + 0.04);
  run.pipeline.add(run.drive.scanAt(0.2), 0.2 + period + 0.01);
  EXPECT_EQ(run.pipeline.waiting(), 1u);  // tf covers the sweep, not its end + 0.1 s
  run.tfUntil(0.2 + period + 0.08);
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.tfUntil(0.2 + period + 0.12);  // tf every 20 ms: the first sample at or after end + 0.1 s
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  ASSERT_EQ(run.results.size(), 1u);
  EXPECT_TRUE(run.results[0].corrected);
  // tf stops 0.04 s after the next sweep: served at tf_timeout with the samples there are.
  const double next = 0.6;
  run.tfUntil(next + period + 0.04);
  run.pipeline.add(run.drive.scanAt(next), next + period + 0.01);
  run.pipeline.expire(next + period + 0.3);
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.pipeline.expire(next + period + 0.32);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  ASSERT_EQ(run.results.size(), 2u);
  EXPECT_TRUE(run.results[1].corrected);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 0u);
  // tf's samples are exact: the corrected points lie on the true walls either way.
  const std::vector<double> distances = run.cloudDistances();
  ASSERT_FALSE(distances.empty());
  EXPECT_LT(*std::max_element(distances.begin(), distances.end()), 1e-3);
}

// Live, every scan waits the look-ahead: a queue too short for it drops scans, and the warning names the
// queue_size that holds them at the rate they come (40 Hz x 0.5 s and two more: 22), which drops none.
TEST(ScanPipeline, QueueTooShortForTheLookAheadNamesTheQueueSizeThatHoldsIt) {
  const auto drive = [](int queue_size) {
    ros_adapter::DeskewParams params;
    params.deskew.interpolation = core::Interpolation::kTwist;
    params.deskew.fit_look_ahead = 0.5;
    params.tf_timeout = 1.0;
    params.queue_size = queue_size;
    auto run = std::make_unique<PipelineRun>(Drive(), params);
    run->statics(0.0);
    for (double t = 0.0; t < 2.0; t += 1.0 / run->drive.model.rate)
      run->scan(t);
    return run;
  };
  const auto short_queue = drive(10);
  EXPECT_GT(short_queue->pipeline.counters().dropped_queue, 20u);
  const auto warning = std::find_if(short_queue->events.begin(), short_queue->events.end(),
                                    [](const auto& e) { return e.first == PipelineEvent::kQueueFull; });
  ASSERT_NE(warning, short_queue->events.end());
  EXPECT_NE(warning->second.find("each waits fit_look_ahead (0.5 s), at 40 Hz queue_size must be 22 or more"),
            std::string::npos)
      << warning->second;
  const auto advised = drive(22);
  EXPECT_EQ(advised->pipeline.counters().dropped_queue, 0u);
  EXPECT_GT(advised->results.size(), 55u);  // 2 s at 40 Hz, less the last 0.5 s still waiting
  EXPECT_FALSE(advised->said(PipelineEvent::kQueueFull));
}

// Waiting is measured on the owner's clock: a scan waits up to tf_timeout for tf, then fails.
TEST(ScanPipeline, ScansWaitOnTheOwnersClockThenFail) {
  for (const auto failure : {ros_adapter::OnTfFailure::kDrop, ros_adapter::OnTfFailure::kPassThrough}) {
    ros_adapter::DeskewParams params;
    params.tf_timeout = 0.2;
    params.on_tf_failure = failure;
    PipelineRun run(Drive(), params);
    run.statics(0.0);
    run.tfUntil(0.10);
    run.pipeline.add(run.drive.scanAt(0.1), 0.125);  // tf covers only its first beam
    run.pipeline.expire(0.3);
    EXPECT_EQ(run.pipeline.waiting(), 1u);  // 0.175 s waited: still within tf_timeout
    run.pipeline.expire(0.33);
    EXPECT_EQ(run.pipeline.waiting(), 0u);
    const bool drop = failure == ros_adapter::OnTfFailure::kDrop;
    EXPECT_EQ(run.pipeline.counters().dropped_tf, drop ? 1u : 0u);
    EXPECT_EQ(run.pipeline.counters().passed_through, drop ? 0u : 1u);
    EXPECT_EQ(run.results.size(), drop ? 0u : 1u);
    // Late tf that comes within tf_timeout is waited for: the next scan is corrected when it comes,
    // 0.15 s after the scan.
    run.pipeline.add(run.drive.scanAt(0.2), 0.4);
    run.pipeline.expire(0.5);
    EXPECT_EQ(run.pipeline.waiting(), 1u);
    run.pipeline.addTransforms({run.drive.motionAt(0.24)}, false, 0.55);
    EXPECT_EQ(run.pipeline.waiting(), 0u);
    EXPECT_EQ(run.pipeline.counters().published, 1u);
    ASSERT_FALSE(run.results.empty());
    EXPECT_NEAR(run.results.back().waited, 0.15, 1e-9);
    // flush(): nothing more will come (the end of a bag).
    run.pipeline.add(run.drive.scanAt(0.3), 0.5);
    run.pipeline.flush();
    EXPECT_EQ(run.pipeline.waiting(), 0u);
    EXPECT_EQ(run.pipeline.counters().dropped_tf + run.pipeline.counters().passed_through, 2u);
  }
}

// Time going back (a bag loop): the tf cache and the waiting scans are cleared once, and the new time
// line is corrected.
TEST(ScanPipeline, TimeJumpClearsTheQueueOnceAndRecovers) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(2.0);
  run.pipeline.add(run.drive.scanAt(3.0), 3.0);  // waits: tf ends at 2 s
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.tf_until = -0.1;  // the bag starts again
  run.tfUntil(0.05);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 1u);  // the waiting scan is accounted for
  for (int k = 0; k < 4; ++k)
    run.scan(0.1 + k * 0.025);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.counters().published, 4u);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
}

// A /clock reset seen only on the owner's clock (no tf of the new time line yet): without it the
// waiting scan would wait until the clock came back to where it was. It is a time jump, once.
TEST(ScanPipeline, ClockResetAloneIsATimeJump) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(2.0);
  run.pipeline.add(run.drive.scanAt(3.0), 3.0);  // waits: tf ends at 2 s
  run.pipeline.expire(0.5);                      // the clock alone goes back 2.5 s
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 1u);
  EXPECT_TRUE(run.said(PipelineEvent::kTimeJump));
  // The new time line, tf from -0.1 s again: no second jump, scans corrected.
  run.tf_until = -0.1;
  for (int k = 0; k < 4; ++k)
    run.scan(0.6 + k * 0.025);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.counters().published, 4u);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
}

// The clock goes back first, then tf of the old time line still on its way, then tf of the new one: one
// jump, and the scan of the new time line waiting meanwhile is corrected. A later reset counts again.
TEST(ScanPipeline, OldTfAfterAClockResetIsTheSameJump) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(2.0);
  run.pipeline.expire(0.1);  // the clock goes back
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  run.pipeline.addTransforms({run.drive.motionAt(2.02)}, false, 0.1);  // old, late
  run.pipeline.add(run.drive.scanAt(0.2), 0.12);                       // the new time line
  run.tf_until = 0.1;
  run.tfUntil(0.3);  // tf goes back against the old one: the same jump
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.counters().published, 1u);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 0u);
  run.tfUntil(5.0);
  run.pipeline.expire(1.0);  // the clock resets again, well after: a new jump
  EXPECT_EQ(run.pipeline.counters().time_jumps, 2u);
}

// tf goes back first, the clock follows (a looped bag, two connections): one jump, and a scan of the
// new time line that came in between waits its tf_timeout from the clock's return, not from the old
// clock (it would otherwise wait for as long as the clock had run).
TEST(ScanPipeline, ClockFollowingTfBackIsTheSameJump) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(5.0);
  const double old_clock = 5.0;
  for (double t = 0.0; t <= 0.1 + 1e-9; t += kTfPeriod)  // tf of the new time line, old clock
    run.pipeline.addTransforms({run.drive.motionAt(t)}, false, old_clock);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  run.pipeline.add(run.drive.scanAt(0.1), old_clock);  // waits for tf up to its end
  run.pipeline.expire(0.14);                           // the clock comes back
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.pipeline.expire(0.14 + run.pipeline.params().tf_timeout + 0.01);  // now it has waited too long
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 1u);
}

// While running, the parameters marked reconfigurable change and take effect; any other is refused,
// named, and nothing changes.
TEST(ScanPipeline, ReconfigureTakesTheLiveParametersAndRefusesTheRest) {
  for (const ros_adapter::ParamSpec& spec : ros_adapter::DeskewParams::specs()) {
    SCOPED_TRACE(spec.name);
    PipelineRun run{Drive()};
    const std::string type = spec.type, choices = spec.choices;
    std::string other;  // a valid value other than the default
    if (type == "bool") {
      other = "true";
    } else if (type == "string") {
      other = choices.empty() ? "elsewhere" : choices.substr(choices.rfind('|') + 1);
    } else {
      other = type == "int" ? std::to_string(std::stoi(spec.default_value) + 1)
                            : std::to_string(std::stod(spec.default_value) + 1e-3 * (spec.max - spec.min));
    }
    std::map<std::string, std::string> given{{spec.name, other}};
    if (spec.name == std::string("use_scan_period"))
      given["scan_period"] = "0.1";  // which it needs
    const ros_adapter::DeskewParams next =
        ros_adapter::DeskewParams::load(ros_adapter::TextParams(given), run.pipeline.params());
    if (spec.reconfigurable) {
      EXPECT_NO_THROW(run.pipeline.reconfigure(next));
    } else {
      try {
        run.pipeline.reconfigure(next);
        ADD_FAILURE() << "taken while running";
      } catch (const core::InvalidInput& error) {
        EXPECT_NE(std::string(error.what()).find(spec.name), std::string::npos) << error.what();
      }
    }
  }
}

// A reconfigured on_tf_failure and tf_timeout apply to the scans waiting; a tf_timeout longer than the
// tf cache holds is refused.
TEST(ScanPipeline, ReconfiguredFailurePolicyApplies) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(0.2);
  run.pipeline.add(run.drive.scanAt(0.3), 0.3);  // its tf never comes
  ros_adapter::DeskewParams next = run.pipeline.params();
  next.on_tf_failure = ros_adapter::OnTfFailure::kPassThrough;
  next.tf_timeout = 0.5;
  run.pipeline.reconfigure(next);
  run.pipeline.expire(0.3 + 0.3);  // past the old timeout, within the new one
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.pipeline.expire(0.3 + 0.6);
  EXPECT_EQ(run.pipeline.counters().passed_through, 1u);
  EXPECT_EQ(run.results.size(), 1u);
  next.tf_timeout = 9.5;  // the cache holds 10 s, less 1 s of sweep and 1 s of margin
  EXPECT_THROW(run.pipeline.reconfigure(next), core::InvalidInput);
  EXPECT_DOUBLE_EQ(run.pipeline.params().tf_timeout, 0.5);
}

// Scans lost upstream show as gaps in header.seq; an unset seq (always 0) or a restart counts nothing.
TEST(ScanPipeline, GapsInSeqAreCountedAsLostUpstream) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(0.05);
  const auto scanWithSeq = [&](std::uint32_t seq, double t) {
    const auto scan = run.drive.scanAt(t);
    scan->header.seq = seq;
    run.pipeline.add(scan, t + 0.025);
    run.tfUntil(t + 0.05);
  };
  for (const std::uint32_t seq : {0u, 0u, 0u})
    scanWithSeq(seq, 0.1);
  EXPECT_EQ(run.pipeline.counters().lost_upstream, 0u);
  scanWithSeq(7, 0.15);
  scanWithSeq(8, 0.2);
  scanWithSeq(11, 0.25);  // 9 and 10 lost
  scanWithSeq(3, 0.3);    // the driver restarted
  scanWithSeq(4, 0.35);
  EXPECT_EQ(run.pipeline.counters().lost_upstream, 2u);
  EXPECT_EQ(run.pipeline.counters().received, 8u);
}

// A scan frame with no mount anywhere is dropped as such once its wait is over, named in the report.
TEST(ScanPipeline, MissingMountIsDroppedAndNamed) {
  PipelineRun run{Drive()};
  run.tfUntil(0.2);
  run.pipeline.add(run.drive.scanAt(0.1), 0.125);
  run.pipeline.expire(1.0);
  EXPECT_EQ(run.pipeline.counters().dropped_mount, 1u);
  ASSERT_TRUE(run.said(PipelineEvent::kMountMissing));
  EXPECT_NE(run.events.back().second.find("base_link -> laser"), std::string::npos)
      << run.events.back().second;
}

/// The last event of `kind` the pipeline reported (empty when none).
std::string lastSaid(const PipelineRun& run, PipelineEvent kind) {
  std::string text;
  for (const auto& [event, said] : run.events) {
    if (event == kind)
      text = said;
  }
  return text;
}

// Stamps tf cannot take: 0 (unset), 2105 (uninitialised: tf2 threw "Duration is out of dual 32-bit
// range" and the scan jammed the queue's head), 1970. Each is dropped as invalid and named when it
// reaches the queue's head; the scans around it are corrected, nothing is blamed on tf.
TEST(ScanPipeline, StampsTfCannotTakeAreDroppedAndTheStreamGoesOn) {
  PipelineRun run{Drive()};
  const auto bad = [&](double t, const ros::Time& stamp) {
    const auto scan = run.drive.scanAt(t);
    scan->header.stamp = stamp;
    return scan;
  };
  // Before any tf: the 2105 scan waits behind nothing, and is judged when tf comes.
  run.pipeline.add(bad(0.05, ros::Time(4'260'211'200, 0)), 0.06);
  EXPECT_EQ(run.pipeline.waiting(), 1u);
  run.statics(0.06);
  run.tfUntil(0.1);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().dropped_invalid, 1u);
  EXPECT_TRUE(holds(lastSaid(run, PipelineEvent::kMalformed), "invalid stamp: the sweep lies"));
  // Each kind between good scans, and one behind a good scan waiting for tf.
  const std::vector<std::pair<ros::Time, std::string>> stamps = {
      {ros::Time(0, 0), "invalid stamp: header.stamp is 0 (unset"},
      {ros::Time(4'260'211'200, 0), "after tf's newest odom -> base_link"},
      {ros::Time(1, 0), "before tf's newest odom -> base_link"}};
  double t = 0.1;
  for (const auto& [stamp, named] : stamps) {
    run.scan(t);
    run.pipeline.add(run.drive.scanAt(t + 0.025), t + 0.05);  // waits for its tf
    run.pipeline.add(bad(t + 0.03, stamp), t + 0.05);         // judged once it is at the head
    run.tfUntil(t + 0.075);
    EXPECT_TRUE(holds(lastSaid(run, PipelineEvent::kMalformed), named));
    t += 0.075;
  }
  const PipelineCounters& counters = run.pipeline.counters();
  EXPECT_EQ(counters.dropped_invalid, 4u);
  EXPECT_EQ(counters.published, 6u);
  EXPECT_EQ(counters.dropped_tf, 0u);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
}

// A scan tf does not cover is dropped, after tf_timeout, with its frames and its cause: a fixed_frame
// unknown to tf (with the closest frame tf knows), tf short of the sweep's end (by how much), a sweep
// ending after its arrival (a driver stamping late), a missing mount (the scan frame misspelt, or the
// base_frame), a base with two parents.
TEST(ScanPipeline, DropsNameTheirCause) {
  ros_adapter::DeskewParams params;
  params.tf_timeout = 0.2;
  const auto dropOne = [](PipelineRun& run, double arrival, PipelineEvent kind,
                          const std::function<void(sensor_msgs::LaserScan&)>& modify = {}) {
    run.statics(0.0);
    run.tfUntil(0.1);
    const auto scan = run.drive.scanAt(0.1);  // [0.1, 0.125]: tf ends at its first beam
    if (modify)
      modify(*scan);
    run.pipeline.add(scan, arrival);
    run.pipeline.expire(arrival + 0.3);
    EXPECT_EQ(run.pipeline.waiting(), 0u);
    return lastSaid(run, kind);
  };
  {
    PipelineRun run(Drive(), params, "odm");
    EXPECT_EQ(dropOne(run, 0.13, PipelineEvent::kTfFailure),
              "dropping scan at 1700000000.100000 (frame laser): fixed_frame 'odm' is unknown to tf (did you "
              "mean 'odom'?); tf's frames: base_link, laser, odom (waited tf_timeout, 0.2 s)");
    EXPECT_EQ(run.pipeline.counters().dropped_tf, 1u);
  }
  {
    PipelineRun run(Drive(), params);
    EXPECT_EQ(dropOne(run, 0.13, PipelineEvent::kTfFailure),
              "dropping scan at 1700000000.100000 (frame laser): tf odom -> base_link has not reached the "
              "sweep's end: its newest is 25.0 ms before it (waited tf_timeout, 0.2 s)");
  }
  {
    // The owner's clock on the stamps' (as live and offline; the other cases keep it apart).
    PipelineRun run(Drive(), params);
    const std::string said =
        dropOne(run, core::nsToSeconds(run.drive.epoch) + 0.11, PipelineEvent::kTfFailure);
    EXPECT_TRUE(holds(said,
                      "tf odom -> base_link ends 25.0 ms before the sweep's end, which lies 15.0 ms "
                      "after the arrival: a driver stamping late"));
    EXPECT_TRUE(holds(said,
                      "Set time_offset (deskew_calibrate finds it from a recording), or give tf "
                      "longer with a longer tf_timeout"));
  }
  {
    PipelineRun run(Drive(), params);
    EXPECT_EQ(
        dropOne(run, 0.13, PipelineEvent::kMountMissing,
                [](sensor_msgs::LaserScan& scan) { scan.header.frame_id = "lasr"; }),
        "dropping scan at 1700000000.100000: no transform base_link -> lasr (the laser mount): the scan's "
        "frame 'lasr' is unknown to tf (did you mean 'laser'?); tf's frames: base_link, laser, odom");
    EXPECT_EQ(run.pipeline.counters().dropped_mount, 1u);
  }
  {
    // A misspelt base_frame: the mount (base -> laser) is looked up first, and names the base.
    PipelineRun run(Drive(), params, "", ros_adapter::Waiting::kTimeout, "base_lnk");
    EXPECT_EQ(dropOne(run, 0.13, PipelineEvent::kMountMissing),
              "dropping scan at 1700000000.100000: no transform base_lnk -> laser (the laser mount): "
              "base_frame 'base_lnk' is unknown to tf (did you mean 'base_link'?); tf's frames: base_link, "
              "laser, odom");
  }
  {
    PipelineRun run(Drive(), params);
    for (double t = 0.0; t <= 0.1; t += 0.05)
      run.pipeline.addTransforms({stamped("map", "base_link", run.drive.stampOf(t + 0.005), {1.0, 2.0, 0.3})},
                                 false, t);
    EXPECT_TRUE(holds(dropOne(run, 0.13, PipelineEvent::kTfFailure),
                      "tf odom -> base_link: base_link has two parents on /tf, map and odom"));
    EXPECT_TRUE(holds(lastSaid(run, PipelineEvent::kTwoParents), "base_link has two parents on /tf"));
  }
}

// A stray publisher of odom -> base_link 3 s stale at 2 Hz beside the real one at 50 Hz (it cleared the
// tf cache at each of its messages: 114 of 139 scans delivered). Its transforms are left out, said
// once and counted; every scan is corrected. A real jump afterwards (three in a row) still clears.
TEST(ScanPipeline, StaleTfOfAStrayPublisherCostsNoScan) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(3.5);
  int scans = 0;
  for (double t = 3.5; t < 7.0; t += 0.025) {
    run.pipeline.add(run.drive.scanAt(t), t + 0.025);
    ++scans;
    run.tfUntil(t + 0.045);
    if (std::fmod(t + 1e-9, 0.5) < 0.025)  // every 0.5 s, the stray one, with a wrong pose
      run.pipeline.addTransforms({stamped("odom", "base_link", run.drive.stampOf(t - 3.0), {9.0, 9.0, 1.0})},
                                 false, t + 0.03);
  }
  run.tfUntil(7.1);
  const PipelineCounters& counters = run.pipeline.counters();
  EXPECT_EQ(counters.published, static_cast<std::uint64_t>(scans));
  EXPECT_EQ(counters.time_jumps, 0u);
  EXPECT_EQ(counters.stale_tf, 7u);
  EXPECT_EQ(std::count_if(run.events.begin(), run.events.end(),
                          [](const auto& e) { return e.first == PipelineEvent::kStaleTf; }),
            1);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
  run.tf_until = 0.0;  // the bag starts again
  run.tfUntil(0.1);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 1u);
}

// A seq that repeats (ROS 2 conversions write 0 for every scan, some drivers repeat theirs) numbers
// no scans: its steps are no losses, until it goes up by one again.
TEST(ScanPipeline, RepeatedSeqCountsNoLosses) {
  PipelineRun run{Drive()};
  run.statics(0.0);
  run.tfUntil(0.05);
  double t = 0.1;
  const auto scanWithSeq = [&](std::uint32_t seq) {
    const auto scan = run.drive.scanAt(t);
    scan->header.seq = seq;
    run.pipeline.add(scan, t + 0.025);
    run.tfUntil(t + 0.05);
    t += 0.025;
  };
  for (const std::uint32_t seq : {5u, 5u, 7u, 7u, 9u, 9u, 12u})
    scanWithSeq(seq);
  EXPECT_EQ(run.pipeline.counters().lost_upstream, 0u);
  for (const std::uint32_t seq : {13u, 14u, 17u})  // numbering again: 15 and 16 lost
    scanWithSeq(seq);
  EXPECT_EQ(run.pipeline.counters().lost_upstream, 2u);
  EXPECT_EQ(run.pipeline.counters().published, 10u);
}

// A recording (Waiting::kRecording) whose tf was recorded 1.5 s after the scans it covers: each scan
// waits until tf passes its last beam, whatever tf_timeout and queue_size say, and is corrected onto
// the true walls. The first scan starts before tf does and the last ends after it: each is dropped
// alone with its own cause, neither holds back the others.
TEST(ScanPipeline, RecordingWaitsForLateTfAndDecidesEachScanAlone) {
  ros_adapter::DeskewParams params;
  params.tf_timeout = 0.2;
  params.queue_size = 10;
  PipelineRun run(Drive(), params, "", ros_adapter::Waiting::kRecording);
  constexpr double kLag = 1.5;  // [s] tf recorded this long after its stamp
  constexpr int kScans = 40;    // [0, 1] s at 40 Hz
  run.statics(0.0);
  double tf_stamp = 0.02;  // tf begins inside the first scan [0, 0.025] and ends inside the last
  std::size_t most_waiting = 0;
  for (int k = 0; k < kScans; ++k) {
    const double start = 0.025 * k;
    for (; tf_stamp + kLag <= start + 0.025 && tf_stamp < 0.99; tf_stamp += kTfPeriod)
      run.pipeline.addTransforms({run.drive.motionAt(tf_stamp)}, false, tf_stamp + kLag);
    run.pipeline.add(run.drive.scanAt(start), start + 0.025);
    run.pipeline.expire(start + 0.025);
    most_waiting = std::max(most_waiting, run.pipeline.waiting());
  }
  for (; tf_stamp < 0.99; tf_stamp += kTfPeriod) {
    run.pipeline.addTransforms({run.drive.motionAt(tf_stamp)}, false, tf_stamp + kLag);
    run.pipeline.expire(tf_stamp + kLag);
  }
  EXPECT_GT(most_waiting, static_cast<std::size_t>(params.queue_size));  // 1.5 s of scans wait
  EXPECT_EQ(run.pipeline.counters().published, static_cast<std::uint64_t>(kScans - 2));
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 1u);  // the first; the last still waits for tf
  run.pipeline.flush();
  const PipelineCounters& counters = run.pipeline.counters();
  EXPECT_EQ(counters.published, static_cast<std::uint64_t>(kScans - 2));
  EXPECT_EQ(counters.dropped_tf, 2u);
  EXPECT_EQ(counters.dropped_queue, 0u);
  const std::map<std::string, std::uint64_t> causes{{"tf began after the sweep's start", 1},
                                                    {"tf never reached the sweep's end", 1}};
  EXPECT_EQ(counters.dropped_by_cause, causes);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
}

/// The corrected points (x, y, z of every cloud, in order) of a recording with noisy odometry (tf at 50 Hz
/// from 0 to 1.6 s, each sample's position off by 3 mm RMS, recorded `lag` s after its stamp) and 16
/// scans at 40 Hz from 0.5 s, recorded at their end, with `fit_look_ahead` = look_ahead.
std::vector<float> noisyRecording(double lag, double look_ahead) {
  ros_adapter::DeskewParams params;
  params.deskew.fit_look_ahead = look_ahead;
  PipelineRun run(Drive(), params, "", ros_adapter::Waiting::kRecording);
  std::mt19937 random(4);
  std::normal_distribution<double> noise(0.0, 0.003);
  struct Message {
    double record_time;
    bool is_tf;
    geometry_msgs::TransformStamped tf;
    double scan_start;
  };
  std::vector<Message> messages;
  for (int k = 0; k <= 80; ++k) {
    geometry_msgs::TransformStamped tf = run.drive.motionAt(k * kTfPeriod);
    tf.transform.translation.x += noise(random);
    tf.transform.translation.y += noise(random);
    messages.push_back({k * kTfPeriod + lag, true, tf, 0.0});
  }
  for (int k = 0; k < 16; ++k)
    messages.push_back({0.5 + 0.025 * (k + 1), false, {}, 0.5 + 0.025 * k});
  std::stable_sort(messages.begin(), messages.end(),
                   [](const Message& a, const Message& b) { return a.record_time < b.record_time; });
  run.statics(0.0);
  for (const Message& message : messages) {
    if (message.is_tf)
      run.pipeline.addTransforms({message.tf}, false, message.record_time);
    else
      run.pipeline.add(run.drive.scanAt(message.scan_start), message.record_time);
    run.pipeline.expire(message.record_time);
  }
  run.pipeline.flush();
  EXPECT_EQ(run.pipeline.counters().published, 16u) << lag << " " << look_ahead;
  std::vector<float> points;
  for (const PipelineResult& result : run.results) {
    for (const auto& point : result.outputs.cloud->points)
      points.insert(points.end(), {point.x, point.y, point.z});
  }
  return points;
}

// A recording with noisy odometry and a look-ahead of the twist fit (fit_look_ahead): each scan waits
// until tf passes its end by the look-ahead, so its correction is the same to the bit whether tf was
// recorded with the scans or 1.5 s after them (when a scan is served, tf may hold more or less after it);
// the look-ahead changes the correction (the noisy fit reads the samples after the sweep).
TEST(ScanPipeline, RecordingWithALookAheadCorrectsTheSameHoweverLateTfCame) {
  const std::vector<float> on_time = noisyRecording(0.0, 0.2), late = noisyRecording(1.5, 0.2);
  ASSERT_GT(on_time.size(), 3000u);
  EXPECT_TRUE(on_time == late);
  EXPECT_FALSE(on_time == noisyRecording(0.0, 0.0));
}

// A recording's scans whose tf never comes wait at most kRecordedTfWait of record time (tf that stopped:
// the memory of a long bag stays bounded), then are dropped, each with its cause.
TEST(ScanPipeline, RecordingGivesUpOnTfThatStopped) {
  PipelineRun run(Drive(), {}, "", ros_adapter::Waiting::kRecording);
  run.statics(0.0);
  run.tfUntil(0.5);
  for (int k = 0; k < 200; ++k)
    run.pipeline.add(run.drive.scanAt(0.6 + 0.025 * k), 0.625 + 0.025 * k);
  EXPECT_EQ(run.pipeline.waiting(), 200u);
  run.pipeline.expire(0.625 + ScanPipeline::kRecordedTfWait + 0.01);  // the first has waited that long
  EXPECT_EQ(run.pipeline.waiting(), 199u);
  run.pipeline.expire(10.0 + ScanPipeline::kRecordedTfWait);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().dropped_tf, 200u);
  EXPECT_EQ(run.pipeline.counters().dropped_by_cause.at("tf never reached the sweep's end"), 200u);
  EXPECT_TRUE(holds(lastSaid(run, PipelineEvent::kTfFailure), "(waited 30 s of record time)"));
}

/// What a recording whose clock restarts gave: the drive for `kRound` s, then the drive again from its
/// start, stamped from 1 s after the first round's epoch (scans and tf go back 5.2 s; the first round's
/// tf cache holds the new stamps, with the other drive's poses), record time going on. tf at 50 Hz
/// recorded `lag` s after its stamp, scans at 40 Hz at their end.
struct RestartedRecording {
  std::size_t scans = 0;
  PipelineCounters counters;
  double rms = 0.0;  ///< [m] of the corrected points to the true walls (each round's own truth)
};

RestartedRecording recordingWithRestart(double lag) {
  constexpr double kRound = 6.0;  // [s]
  sim::LidarModel model = sim::LidarModel::utm30lx360();
  model.beams = 180;  // 2 degree steps: the test in seconds, the timing the UTM-30LX's
  PipelineRun run(Drive(TfTree(), model), {}, "", ros_adapter::Waiting::kRecording);
  Drive restarted = run.drive;
  restarted.epoch += core::secondsToNs(1.0);
  const Drive* const rounds[] = {&run.drive, &restarted};
  // Every message of both rounds by record time: tf's (round, t) and scans' (round, first beam).
  struct Message {
    double record;
    int round;
    double t;
    bool scan;
  };
  std::vector<Message> messages;
  RestartedRecording recording;
  for (int round = 0; round < 2; ++round) {
    const double clock_start = round * (kRound + lag + 1.0);
    for (int k = -5; k <= static_cast<int>(std::lround(kRound / kTfPeriod)) + 5; ++k)
      messages.push_back({clock_start + k * kTfPeriod + lag, round, k * kTfPeriod, false});
    for (int k = 0; k < static_cast<int>(std::lround(kRound * 40)); ++k, ++recording.scans)
      messages.push_back({clock_start + 0.025 * (k + 1), round, 0.025 * k, true});
  }
  std::stable_sort(messages.begin(), messages.end(),
                   [](const Message& a, const Message& b) { return a.record < b.record; });
  int statics_sent = -1;
  for (const Message& message : messages) {
    const Drive& drive = *rounds[message.round];
    if (statics_sent < message.round) {  // latched /tf_static, recorded again as the drive restarts
      run.pipeline.addTransforms(drive.statics(), true, message.record);
      statics_sent = message.round;
    }
    if (message.scan)
      run.pipeline.add(drive.scanAt(message.t), message.record, message.round);
    else
      run.pipeline.addTransforms({drive.motionAt(message.t)}, false, message.record);
    run.pipeline.expire(message.record);
  }
  run.pipeline.flush();
  recording.counters = run.pipeline.counters();
  std::vector<double> distances;
  for (const PipelineResult& result : run.results) {
    if (!result.corrected)
      continue;
    for (double d :
         rounds[result.id]->distances(result.outputs.cloud->points, result.outputs.scan->header.stamp))
      distances.push_back(d);
  }
  recording.rms = rms(distances);
  return recording;
}

// A recording whose clock restarts (a simulator restarted while recording), tf recorded 0, 1.5 or 2.5 s
// after the scans it covers: the new time line's scans come before any tf of it, tf's newest still on
// the old line. They wait for tf's jump and on across it: every scan is corrected onto its own drive's
// walls. Before, those scans were served from the old line's tf cache, with the other drive's poses
// (1.5 s: 33.8 mm RMS over all 480 scans), or dropped when their tf came more than 1 s after them
// (2.5 s: 478 of 480, "time went backwards"); 0 s was right.
TEST(ScanPipeline, RecordingWhoseClockRestartsCorrectsEveryScan) {
  for (const double lag : {0.0, 1.5, 2.5}) {
    const RestartedRecording recording = recordingWithRestart(lag);
    std::printf("clock restart, tf %.1f s late: %llu of %zu scans corrected, %llu time jumps, rms %.3f mm\n",
                lag, static_cast<unsigned long long>(recording.counters.published), recording.scans,
                static_cast<unsigned long long>(recording.counters.time_jumps), 1e3 * recording.rms);
    EXPECT_EQ(recording.counters.time_jumps, 1u) << lag;
    EXPECT_EQ(recording.counters.published, recording.scans) << lag;
    EXPECT_LT(recording.rms, 1e-3) << lag;
  }
}

// One scan stamped 1.6 s back in a recording, the stream going on as before: the scans' stamps went
// back, but the next scan is on tf's time line again, so is the one stamped back. It is corrected
// (from tf's cache) as any other, not held for a time jump that never comes.
TEST(ScanPipeline, RecordingScanStampedBackOnceIsCorrected) {
  PipelineRun run(Drive(), {}, "", ros_adapter::Waiting::kRecording);
  run.statics(0.0);
  run.tfUntil(2.0);
  for (int k = 0; k < 4; ++k)
    run.scan(2.0 + 0.025 * k);
  run.pipeline.add(run.drive.scanAt(0.5), 2.1);  // 1.6 s behind the scans and tf
  EXPECT_EQ(run.pipeline.waiting(), 1u);         // the time line of the scans may have restarted
  for (int k = 4; k < 8; ++k)
    run.scan(2.0 + 0.025 * k);
  EXPECT_EQ(run.pipeline.waiting(), 0u);
  EXPECT_EQ(run.pipeline.counters().published, 9u);
  EXPECT_EQ(run.pipeline.counters().time_jumps, 0u);
  EXPECT_LT(rms(run.cloudDistances()), 1e-3);
}

/// What a 60 s drive gave: scans at 40 Hz arriving at their end, tf at 50 Hz, the clock on the stamps'
/// time line plus `clock_offset` [s]; beside it a stray publisher of odom -> base_link (the true pose
/// stamped `stray_offset` s off) at `stray_rate` Hz (0: none).
struct StrayDrive {
  PipelineCounters counters;
  double rms = 0.0;  ///< [m] of the corrected points to the true walls
  std::size_t scans = 0;
  std::uint64_t loop_jumps = 0;      ///< time jumps when the drive starts again (a bag loop, clock on)
  std::uint64_t loop_published = 0;  ///< scans of the loop's 2 s corrected
  std::size_t loop_scans = 0;
};

StrayDrive driveWithStray(double stray_offset, double stray_rate) {
  sim::LidarModel model = sim::LidarModel::utm30lx360();
  model.beams = 180;  // 2 degree steps: the test in seconds, the timing the UTM-30LX's
  PipelineRun run{Drive(TfTree(), model)};
  run.statics(0.0);
  StrayDrive drive;
  const int stray_every = stray_rate > 0.0 ? static_cast<int>(std::lround(200.0 / stray_rate)) : 0;
  // 5 ms ticks: tf every 4th, a scan ending every 5th, the stray publisher every `stray_every`.
  const auto play = [&](int ticks, double clock_start) {
    for (int i = 0; i <= ticks; ++i) {
      const double t = 0.005 * i, now = clock_start + t;
      if (i % 4 == 0)
        run.pipeline.addTransforms({run.drive.motionAt(t)}, false, now);
      if (stray_every > 0 && i % stray_every == 0 && t >= 1.0) {
        geometry_msgs::TransformStamped stray = run.drive.motionAt(t);
        stray.header.stamp = run.drive.stampOf(t + stray_offset);
        run.pipeline.addTransforms({stray}, false, now);
      }
      if (i % 5 == 0 && i > 0) {
        run.pipeline.add(run.drive.scanAt(t - 0.025), now);
        ++drive.scans;
      }
      run.pipeline.expire(now);
    }
  };
  play(12000, 0.0);  // 60 s
  drive.counters = run.pipeline.counters();
  const std::size_t loop_start = drive.scans;
  std::vector<double> distances;  // of every 10th scan's points (all of them: seconds)
  for (std::size_t k = 0; k < run.results.size(); k += 10) {
    const PipelineResult& result = run.results[k];
    for (double d : run.drive.distances(result.outputs.cloud->points, result.outputs.scan->header.stamp))
      distances.push_back(d);
  }
  drive.rms = rms(distances);
  run.results.clear();
  play(400, 61.0);  // the drive again, 2 s of it, the clock going on (rosbag play -l without --clock)
  drive.loop_jumps = run.pipeline.counters().time_jumps - drive.counters.time_jumps;
  drive.loop_published = run.pipeline.counters().published - drive.counters.published;
  drive.loop_scans = drive.scans - loop_start;
  drive.scans = loop_start;
  return drive;
}

// A second publisher of odom -> base_link on another clock, 3 s ahead at 2 or 10 Hz or 3 s behind at
// 200 Hz, beside tf at 50 Hz over a 60 s drive (2,182, 1,318 and 239 of 2,400 scans published: each of
// its messages passed for a time jump). The scans' stamps tell the real time line: every scan is
// corrected as without the stray publisher, no time jump; the stray transforms are counted by kind and
// said once each. A real bag loop afterwards is still one jump, and its scans are corrected.
TEST(ScanPipeline, StrayPublisherOnAnotherClockIsNoTimeJump) {
  const StrayDrive clean = driveWithStray(0.0, 0.0);
  ASSERT_EQ(clean.scans, 2400u);
  EXPECT_EQ(clean.counters.published, 2400u);
  EXPECT_LT(clean.rms, 1e-3);
  EXPECT_EQ(clean.loop_jumps, 1u);
  EXPECT_GE(clean.loop_published + 2, clean.loop_scans);
  struct Case {
    double offset, rate;
    std::uint64_t stray;  // its transforms, all left out
  };
  for (const Case& c : {Case{3.0, 2.0, 119}, Case{3.0, 10.0, 591}, Case{-3.0, 200.0, 11801}}) {
    const StrayDrive drive = driveWithStray(c.offset, c.rate);
    std::printf(
        "stray tf %+.0f s at %.0f Hz: %llu of %zu scans corrected, %llu time jumps, rms %.3f mm "
        "(clean %.3f)\n",
        c.offset, c.rate, static_cast<unsigned long long>(drive.counters.published), drive.scans,
        static_cast<unsigned long long>(drive.counters.time_jumps), 1e3 * drive.rms, 1e3 * clean.rms);
    EXPECT_GE(drive.counters.published, 0.98 * drive.scans) << c.rate;
    EXPECT_EQ(drive.counters.published, clean.counters.published) << c.rate;
    EXPECT_EQ(drive.counters.time_jumps, 0u) << c.rate;
    EXPECT_NEAR(drive.rms, clean.rms, 1e-9) << c.rate;
    EXPECT_EQ(c.offset > 0.0 ? drive.counters.ahead_tf : drive.counters.stale_tf, c.stray) << c.rate;
    EXPECT_EQ(drive.loop_jumps, 1u) << c.rate;
    EXPECT_GE(drive.loop_published + 2, drive.loop_scans) << c.rate;
  }
}

}  // namespace
}  // namespace lidar_deskew::test
