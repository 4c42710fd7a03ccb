// The per-scan pipeline of the live node and deskew_bag (docs/DESIGN.md §2): tf and
// scans in, in arrival order; each scan waits until tf covers its last beam, then is corrected (or
// dropped / passed through) and handed to the owner. Waiting is measured on a clock the owner gives:
// wall time live, record time offline.
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/LaserScan.h>

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lidar_deskew/ros/cloud_processor.h"
#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/scan_processor.h"
#include "lidar_deskew/ros/tf_feed.h"

namespace lidar_deskew::ros_adapter {

/// What happened to the scans; the node's diagnostics and deskew_bag's summary show these.
struct PipelineCounters {
  std::uint64_t received = 0;
  std::uint64_t published = 0;        ///< corrected scans
  std::uint64_t passed_through = 0;   ///< published uncorrected (on_tf_failure: pass_through)
  std::uint64_t extrapolated = 0;     ///< corrected with tf extrapolated up to max_extrapolation
  std::uint64_t dropped_invalid = 0;  ///< malformed scans
  std::uint64_t dropped_tf = 0;       ///< tf did not cover the sweep within tf_timeout
  std::uint64_t dropped_mount = 0;    ///< no transform base_frame -> scan frame
  std::uint64_t dropped_queue = 0;    ///< more than queue_size scans were waiting
  std::uint64_t time_fallbacks = 0;   ///< scans timed by scan_time or scan_period (time_increment 0)
  std::uint64_t tf_gaps = 0;          ///< refused: tf has a gap longer than max_tf_gap in the sweep
  std::uint64_t mount_changes = 0;    ///< the mount base_frame -> scan frame changed
  /// Time went backwards, in tf's stamps or on the owner's clock (a bag loop, a /clock reset): the tf
  /// cache cleared, the waiting scans failed (dropped or passed through, and counted so).
  std::uint64_t time_jumps = 0;
  std::uint64_t statics_ignored = 0;  ///< /tf_static parents of moving frames left out
  /// /tf transforms stamped over 1 s before their link's newest while its time line went on (a stray
  /// publisher of stale tf): left out, the tf cache kept.
  std::uint64_t stale_tf = 0;
  /// /tf transforms stamped over 1 s after their link's newest, off the time line of the scans (or of
  /// the clock before the first scan): a stray publisher on a clock ahead. Left out, the tf cache kept.
  std::uint64_t ahead_tf = 0;
  /// Scans lost before the pipeline saw them (a driver's, the network's or roscpp's input queue), from
  /// gaps in header.seq; 0 when the driver leaves seq unset (0) or repeats it.
  std::uint64_t lost_upstream = 0;
  /// Every scan dropped (invalid, mount, queue, tf) by its cause ("tf never reached the sweep's end"):
  /// short, fixed texts, one per kind of cause; the reports give each scan's details.
  std::map<std::string, std::uint64_t> dropped_by_cause;
  /// Every scan passed through uncorrected (on_tf_failure: pass_through) by its cause.
  std::map<std::string, std::uint64_t> passed_by_cause;
};

/// The counters by the names the node's diagnostics and deskew_bag's summary both show them.
std::vector<std::pair<std::string, std::uint64_t>> namedCounters(const PipelineCounters& counters);

/// Everything the pipeline has to say, by kind: the owner logs (throttled) or prints it.
enum class PipelineEvent {
  kMalformed,      ///< a scan was dropped as malformed (error)
  kTimeFallback,   ///< the first scan timed without time_increment (warning, once)
  kQueueFull,      ///< the oldest waiting scan was dropped (warning)
  kTfFailure,      ///< a scan was dropped or passed through: tf did not cover it (warning)
  kMountMissing,   ///< a scan was dropped: no mount (error)
  kMountFirst,     ///< the first mount of a scan frame (info)
  kMountChanged,   ///< the mount changed (info)
  kStaticIgnored,  ///< a /tf_static parent of a moving frame left out (warning, once per frame)
  kTimeJump,       ///< time went backwards (warning)
  kBadTransform,   ///< a transform was refused (warning)
  kStaleTf,        ///< stale /tf transforms left out, or ones ahead (warning, once for each)
  kTwoParents,     ///< a frame has two parents on /tf (warning, once per frame)
  kTimingFound,    ///< how the first message was timed, and again whenever that changes (info)
};

/// How long a scan waits for tf (docs/DESIGN.md §2).
enum class Waiting {
  /// Live: until tf covers the sweep, and passes its end by fit_look_ahead with interpolation twist, or
  /// tf_timeout has passed on the owner's clock (then served with what there is); scans are served in
  /// arrival order (a waiting scan holds back those behind it); at most queue_size wait.
  kTimeout,
  /// Offline (a recording, fed in record order): until tf's newest stamp on the fixed -> base chain
  /// passes the sweep's last beam, by fit_look_ahead with interpolation twist (served with what there is
  /// when its wait is over, and at flush()). Then it is served, or failed alone with its cause when tf
  /// does not cover it (tf no longer holds its start, tf began after it); a scan does not hold back
  /// those behind it. When the scans' stamps went back by more than 1 s (a recording whose clock restarts)
  /// and tf has not followed yet, the scans of the new time line more than 1 s behind tf's newest wait
  /// for tf's jump (it would serve them from the old time line), and all of them wait on across it.
  /// Neither tf_timeout nor queue_size drops a scan tf will cover: a scan still waiting after
  /// kRecordedTfWait (or tf_timeout, if longer) on the owner's clock fails (tf stopped, or never comes:
  /// this bounds the memory of a long recording), and flush() decides every scan alone.
  kRecording,
};

/// A sweep's outputs, handed to the owner.
template <class Outputs>
struct SweepResult {
  Outputs outputs;
  bool corrected = false;   ///< false: passed through uncorrected
  double waited = 0.0;      ///< [s] on the owner's clock, from arrival until tf covered it
  double correction = 0.0;  ///< [s] wall time spent correcting and building the messages
  std::uint64_t id = 0;     ///< what the owner gave add() for this sweep (deskew_bag: its record time)
};
using PipelineResult = SweepResult<DeskewedOutputs>;

/// Not thread-safe: the owner serialises calls.
/// One pipeline for every kind of sweep: `Processor` (ScanProcessor for LaserScans, CloudProcessor for
/// PointCloud2s) prepares a message (checked, every point timed: Prepared::earliest() / latest()),
/// corrects it and builds its outputs, or passes it through.
template <class Processor>
class SweepPipeline {
 public:
  using Message = typename Processor::Message;
  using Result = SweepResult<typename Processor::Outputs>;
  using Publish = std::function<void(const Result&)>;
  using Report = std::function<void(PipelineEvent, const std::string&)>;

  /// [s] Waiting::kRecording: the longest a scan waits on the owner's clock (record time) for tf that
  /// does not come, unless tf_timeout is longer.
  static constexpr double kRecordedTfWait = 30.0;

  /// Throws core::InvalidInput for invalid parameters. `tf_cache_time` [s] of dynamic tf kept (at
  /// least the longest wait + max_sweep_duration + 1 s, so a waiting scan's tf is never forgotten;
  /// the longest wait is tf_timeout, or with Waiting::kRecording kRecordedTfWait if longer).
  SweepPipeline(const DeskewParams& params, Publish publish, Report report, double tf_cache_time = 10.0,
                Waiting waiting = Waiting::kTimeout);
  SweepPipeline(const SweepPipeline&) = delete;  // its tf feed reports to `this`
  SweepPipeline& operator=(const SweepPipeline&) = delete;

  /// Every `now` below is on the owner's clock. When it goes back by more than a second and tf has not
  /// (a /clock reset seen first, or alone), that is a time jump as when tf's stamps go back.
  /// Transforms from /tf or /tf_static at `now` [s]; serves the scans they complete.
  void addTransforms(const std::vector<geometry_msgs::TransformStamped>& transforms, bool is_static,
                     double now);
  /// A scan arriving at `now` [s]: checked (one stamped 0, unset, is dropped as invalid), queued,
  /// served if tf already covers it. `id` comes back with its result.
  void add(const typename Message::ConstPtr& message, double now, std::uint64_t id = 0);
  /// Serves the scans tf covers. Waiting::kTimeout: in arrival order (a waiting scan holds back those
  /// behind it); a scan whose times tf cannot take (TfFeed::Coverage::kNever: far from tf's time
  /// line) is dropped as invalid when it reaches the head. Waiting::kRecording: each scan alone, once
  /// tf's newest passes its last beam (served, or failed with its cause), kNever ones at once, but not
  /// those of a time line of the scans that tf has not followed yet (Waiting::kRecording). None is
  /// served while tf went back undecided (TfFeed::jumpPending).
  void serveReady(double now);
  /// The scans that have waited too long at `now` [s] (tf_timeout; Waiting::kRecording: the longer of
  /// it and kRecordedTfWait): extrapolated when max_extrapolation allows, else failed (dropped or
  /// passed through).
  void expire(double now);
  /// Nothing more will come (the end of a bag): decides every waiting scan alone, serving those tf
  /// covers and failing each of the others with its own cause.
  void flush();

  /// Takes the parameters that may change while running (DeskewParams::reconfigurableNames) from
  /// `next`: they apply to scans that arrive (stamp_at, scan_period) or are served (the rest) from now
  /// on. The others must equal the running ones, and tf_timeout must fit the tf cache. Throws
  /// core::InvalidInput naming the parameter; nothing changes then.
  void reconfigure(const DeskewParams& next);

  /// Replaces the receiver of the outputs.
  void setPublish(Publish publish) { publish_ = std::move(publish); }
  /// Called after each sweep corrected with tf's own motion (not extrapolated), with the sweep as
  /// prepared and the mount used (the node's live timing check looks at them with tf().motion()).
  using Corrected = std::function<void(const typename Processor::Prepared&, const mrpt::poses::CPose3D&)>;
  void setCorrected(Corrected corrected) { corrected_ = std::move(corrected); }

  const PipelineCounters& counters() const { return counters_; }
  std::size_t waiting() const { return pending_.size(); }
  const DeskewParams& params() const { return params_; }
  const TfFeed& tf() const { return tf_; }

 private:
  struct Pending {
    typename Processor::Prepared prepared;
    std::string frame;  // normalised frame id
    double arrival = 0.0;
    std::uint64_t id = 0;
    bool covered = false;  // Waiting::kRecording: tf covers it; it waits for its mount
    /// The scans' time line it came on (scan_line_ then).
    std::uint64_t line = 0;
  };

  /// Every call's `now` passes here: the clock going back by more than a second is a time jump (a /clock
  /// reset seen before any tf of the new time line, or alone), unless tf's stamps went back just before.
  void observeClock(double now);
  /// Fails every waiting scan (dropped without a mount, else per on_tf_failure): their tf will not come.
  /// With `new_time_line` [ns] (tf jumped back to it), the scans whose latest time lies within 1 s of it
  /// keep waiting: their tf is the new one; so do the scans that came on the scans' time line `keep_line`.
  void failWaiting(const std::string& reason, core::TimeNs new_time_line = 0,
                   std::optional<std::uint64_t> keep_line = std::nullopt);
  /// Waiting::kRecording: the sweep came on a time line of the scans that tf has not followed (their
  /// stamps went back by more than 1 s since), and lies more than 1 s behind tf's newest `newest` [ns]:
  /// tf still on the old time line, whose cache would serve it with the old motion.
  bool onOtherLine(const Pending& pending, core::TimeNs newest) const;
  /// Waiting::kRecording: gives the sweep its time line of the scans (a new one when its stamps go back
  /// by more than 1 s).
  void noteScanLine(Pending& pending);
  /// Waiting::kRecording's serveReady: each scan decided alone once tf's newest passes its end.
  void serveRecorded(double now);
  /// [s] How long a scan waits for tf that does not come.
  double longestWait() const;
  /// Drops a sweep whose stamp tf cannot take, counted as invalid.
  void dropInvalid(const Pending& pending, const std::string& why);
  /// Drops a sweep without its mount; `error` (tf2's) or else the cause TfFeed finds.
  void dropForMount(const Pending& pending, const std::string& error);
  /// The cause of tf not covering the sweep (TfFeed::whyNotCovered).
  std::string whyNotCovered(const Pending& pending) const;
  /// The kind of that cause, a short fixed text for the counts by cause: tf went back undecided, no tf
  /// between the frames, tf short of the sweep's end, tf not holding its start.
  std::string causeNotCovered(const Pending& pending) const;
  /// tf ends inside the sweep, at most max_extrapolation before its last beam.
  bool extrapolatable(const Pending& pending) const;
  /// With a look-ahead: tf covers the sweep (and its mount) but stopped short of the look-ahead; served
  /// with what there is when its wait is over (tf_timeout live).
  bool coveredWithoutLookAhead(const Pending& pending) const;
  /// For a queue-full warning: the queue_size that holds the scans waiting for the look-ahead at the rate
  /// they arrive, when the queue holds fewer ("" otherwise).
  std::string queueAdvice() const;
  /// [ns] fit_look_ahead with interpolation twist, else 0.
  core::TimeNs lookAheadNs() const;
  void correct(const Pending& pending, bool extrapolate, double now);
  /// Drops the sweep or passes it through (on_tf_failure), counted under `cause` (a short fixed text),
  /// reported with `reason` (its details).
  void fail(const Pending& pending, const std::string& cause, const std::string& reason);
  /// A sweep not covered by tf: fail() with its cause found, `suffix` added to the report.
  void failNotCovered(const Pending& pending, const std::string& suffix);
  void onTfEvent(TfEvent event, const std::string& text);

  DeskewParams params_;
  Waiting waiting_;
  Publish publish_;
  Corrected corrected_;
  Report report_;
  TfFeed tf_;
  Processor processor_;
  std::deque<Pending> pending_;
  PipelineCounters counters_;
  std::optional<std::uint32_t> last_seq_;  // header.seq of the last scan received
  bool seq_repeated_ = false;              // it repeated, and has not gone up by one since
  core::TimeNs tf_began_ = 0;  // [ns] the first time tf answered fixed -> base at (since a time jump)
  std::optional<double> clock_;            // [s] the newest `now` given (since the last time jump)
  bool clock_follows_tf_ = false;          // tf went back; the clock going back next is the same jump
  double tf_jump_clock_ = 0.0;             // [s] the clock when tf went back (the mark expires 2 s on)
  bool tf_follows_clock_ = false;          // the clock went back; tf going back next is the same jump
  double clock_jump_clock_ = 0.0;          // [s] the clock after it went back (the mark expires 2 s on)
  /// The scans' time lines: a new one each time their stamps go back by more than 1 s (Pending::line).
  std::uint64_t scan_line_ = 0;
  std::optional<core::TimeNs> scan_line_newest_;  // [ns] the newest latest beam on it
  std::uint64_t tf_line_ = 0;                     // the scans' time line tf is known to be on
  std::string timing_found_;               // how the last message was timed (Prepared::timingFound)
};

using ScanPipeline = SweepPipeline<ScanProcessor>;
using CloudPipeline = SweepPipeline<CloudProcessor>;
extern template class SweepPipeline<ScanProcessor>;
extern template class SweepPipeline<CloudProcessor>;

std::string toString(PipelineEvent event);

}  // namespace lidar_deskew::ros_adapter
