#include "lidar_deskew/ros/scan_pipeline.h"

#include <algorithm>
#include <chrono>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

/// tf, and beyond its newest sample up to `limit`, the newest velocity (from the last two samples).
class ExtrapolatingMotion final : public core::MotionSource {
 public:
  ExtrapolatingMotion(const TfMotionSource& tf, core::TimeNs newest, core::TimeNs previous,
                      core::TimeNs limit)
      : tf_(tf), newest_(newest), previous_(previous), limit_(limit) {}
  mrpt::poses::CPose3D basePose(core::TimeNs time) const override {
    if (time <= newest_ || time > limit_ || previous_ >= newest_)
      return tf_.basePose(time);
    const double fraction = static_cast<double>(time - previous_) / static_cast<double>(newest_ - previous_);
    return core::interpolatePose(tf_.basePose(previous_), tf_.basePose(newest_), fraction);
  }
  void appendSampleTimes(core::TimeNs begin, core::TimeNs end,
                         std::vector<core::TimeNs>& times) const override {
    tf_.appendSampleTimes(begin, end, times);
  }
  /// Gaps of tf up to its newest sample; beyond it the extrapolation is bounded by max_extrapolation.
  core::TimeNs longestGap(core::TimeNs begin, core::TimeNs end) const override {
    return tf_.longestGap(begin, std::min(end, newest_));
  }

 private:
  const TfMotionSource& tf_;
  core::TimeNs newest_, previous_, limit_;
};

/// A larger jump of header.seq is taken for a driver that restarted, not for lost scans.
constexpr std::uint32_t kMaxSeqGap = 100000;

/// [s] The owner's clock going back by more than this is a time jump (as tf's stamps: TfFeed).
constexpr double kClockJump = 1.0;
/// [ns] kClockJump: scans' stamps going back by more than this start a new time line of the scans.
constexpr core::TimeNs kClockJumpNs = 1'000'000'000;

// The causes scans are counted under (PipelineCounters::dropped_by_cause, passed_by_cause).
const char* const kCauseMalformed = "malformed";
const char* const kCauseStampUnset = "header.stamp 0 (unset)";
const char* const kCauseStamp = "a stamp tf cannot take";
const char* const kCauseMount = "no laser mount in tf";
const char* const kCauseQueue = "more than queue_size waiting";
const char* const kCauseTimeJump = "time went backwards";
const char* const kCauseUndecided = "tf went back in time, undecided";
const char* const kCauseEndLive = "tf did not reach the sweep's end within tf_timeout";
const char* const kCauseEnd = "tf never reached the sweep's end";
const char* const kCauseOtherLine = "tf stayed on another time line";
const char* const kCauseBegan = "tf began after the sweep's start";
const char* const kCauseStart = "tf no longer held the sweep's start";
const char* const kCauseTfGap = "tf gap longer than max_tf_gap";
const char* const kCauseMotion = "motion unavailable";

}  // namespace

std::vector<std::pair<std::string, std::uint64_t>> namedCounters(const PipelineCounters& c) {
  return {{"received", c.received},
          {"published", c.published},
          {"passed through", c.passed_through},
          {"extrapolated", c.extrapolated},
          {"dropped: invalid", c.dropped_invalid},
          {"dropped: tf", c.dropped_tf},
          {"dropped: mount", c.dropped_mount},
          {"dropped: queue", c.dropped_queue},
          {"timing fallbacks", c.time_fallbacks},
          {"tf gaps", c.tf_gaps},
          {"mount changes", c.mount_changes},
          {"time jumps", c.time_jumps},
          {"statics ignored", c.statics_ignored},
          {"stale tf ignored", c.stale_tf},
          {"lost upstream", c.lost_upstream},
          {"tf ahead ignored", c.ahead_tf}};
}

std::string toString(PipelineEvent event) {
  switch (event) {
    case PipelineEvent::kMalformed:
      return "malformed message";
    case PipelineEvent::kTimeFallback:
      return "timing fallback";
    case PipelineEvent::kQueueFull:
      return "queue full";
    case PipelineEvent::kTfFailure:
      return "tf failure";
    case PipelineEvent::kMountMissing:
      return "mount missing";
    case PipelineEvent::kMountFirst:
      return "mount";
    case PipelineEvent::kMountChanged:
      return "mount changed";
    case PipelineEvent::kStaticIgnored:
      return "static ignored";
    case PipelineEvent::kTimeJump:
      return "time jump";
    case PipelineEvent::kBadTransform:
      return "bad transform";
    case PipelineEvent::kStaleTf:
      return "stale tf";
    case PipelineEvent::kTwoParents:
      return "two parents";
    case PipelineEvent::kTimingFound:
      return "timing";
  }
  return "event";
}

template <class Processor>
SweepPipeline<Processor>::SweepPipeline(const DeskewParams& params, Publish publish, Report report,
                                        double tf_cache_time, Waiting waiting)
    : params_((params.validate(), params)),
      waiting_(waiting),
      publish_(std::move(publish)),
      report_(std::move(report)),
      tf_(params.fixed_frame, params.base_frame,
          std::max(tf_cache_time, longestWait() + params.timing.max_sweep_duration + 1.0),
          [this](TfEvent event, const std::string& text) { onTfEvent(event, text); }),
      processor_(params) {}

template <class Processor>
double SweepPipeline<Processor>::longestWait() const {
  return waiting_ == Waiting::kRecording ? std::max(params_.tf_timeout, kRecordedTfWait) : params_.tf_timeout;
}

template <class Processor>
void SweepPipeline<Processor>::reconfigure(const DeskewParams& next) {
  next.validate();
  const auto fixed = [](bool same, const char* name) {
    if (!same)
      throw core::InvalidInput(name, "cannot change while running; restart with it set");
  };
  fixed(next.fixed_frame == params_.fixed_frame, "fixed_frame");
  fixed(next.base_frame == params_.base_frame, "base_frame");
  fixed(next.timing.max_sweep_duration == params_.timing.max_sweep_duration, "max_sweep_duration");
  fixed(next.exact == params_.exact, "exact");  // before knot_interval, which exact sets to 0
  fixed(next.deskew.knot_interval == params_.deskew.knot_interval, "knot_interval");
  fixed(next.deskew.interpolation == params_.deskew.interpolation, "interpolation");
  fixed(next.deskew.fit_look_ahead == params_.deskew.fit_look_ahead, "fit_look_ahead");
  fixed(next.input_queue_size == params_.input_queue_size, "input_queue_size");
  fixed(next.cloud_scan.enabled == params_.cloud_scan.enabled, "cloud_scan");  // its publisher
  fixed(next.cloud_time.field == params_.cloud_time.field, "time_field");
  fixed(next.cloud_time.unit == params_.cloud_time.unit, "time_unit");
  fixed(next.cloud_time.base == params_.cloud_time.base, "time_base");
  fixed(next.azimuth.enabled == params_.azimuth.enabled, "azimuth_timing");
  fixed(next.azimuth.direction == params_.azimuth.direction, "azimuth_direction");
  fixed(next.azimuth.period == params_.azimuth.period, "azimuth_period");
  fixed(next.azimuth.stamp_at == params_.azimuth.stamp_at, "azimuth_stamp_at");
  // A waiting scan's tf must stay in the cache for as long as it may wait.
  const double longest = tf_.cacheTime() - next.timing.max_sweep_duration - 1.0;
  if (next.tf_timeout > longest) {
    throw core::InvalidInput("tf_timeout", "must be at most " + formatNumber(longest) +
                                               " s while running (the tf cache holds " +
                                               formatNumber(tf_.cacheTime()) + " s); restart with it set");
  }
  Processor processor(next);  // may refuse `next` too: then nothing changed
  params_ = next;
  processor_ = std::move(processor);
}

template <class Processor>
void SweepPipeline<Processor>::onTfEvent(TfEvent event, const std::string& text) {
  switch (event) {
    case TfEvent::kStaticIgnored:
      ++counters_.statics_ignored;
      report_(PipelineEvent::kStaticIgnored, text);
      break;
    case TfEvent::kTimeJump: {
      tf_began_ = 0;  // the cache holds the new time line only
      // tf jumped onto the scans' time line (TfFeed follows the newest scan's): the scans that came on it
      // since their stamps went back are its, however long before tf they came.
      const bool scans_went_back = scan_line_ != tf_line_;
      tf_line_ = scan_line_;
      if (tf_follows_clock_) {
        // The clock went back first (counted then) and old tf came after it; the cache now holds the
        // new time line, and the scans waiting belong to it.
        tf_follows_clock_ = false;
        break;
      }
      ++counters_.time_jumps;
      report_(PipelineEvent::kTimeJump,
              text + " and the waiting " + std::string(Processor::kNoun) + "s of the old time line");
      failWaiting(
          "time went backwards", tf_.jumpedTo(),
          waiting_ == Waiting::kRecording && scans_went_back ? std::optional(scan_line_) : std::nullopt);
      clock_follows_tf_ = true;  // the owner's clock may follow tf back: that is this jump, not another
      tf_jump_clock_ = clock_.value_or(0.0);
      break;
    }
    case TfEvent::kBadTransform:
      report_(PipelineEvent::kBadTransform, text);
      break;
    case TfEvent::kStaleIgnored:
      if (counters_.stale_tf++ == 0)  // once; the count is in the counters
        report_(PipelineEvent::kStaleTf, text + " (counted as 'stale tf ignored'; the tf cache is kept)");
      break;
    case TfEvent::kAheadIgnored:
      if (counters_.ahead_tf++ == 0)  // once; the count is in the counters
        report_(PipelineEvent::kStaleTf, text + " (counted as 'tf ahead ignored'; the tf cache is kept)");
      break;
    case TfEvent::kTwoParents:
      report_(PipelineEvent::kTwoParents, text);
      break;
    case TfEvent::kMountFirst:
      report_(PipelineEvent::kMountFirst, "mount " + text);
      break;
    case TfEvent::kMountChanged:
      ++counters_.mount_changes;
      report_(PipelineEvent::kMountChanged, "mount changed (counted): " + text);
      break;
  }
}

template <class Processor>
void SweepPipeline<Processor>::observeClock(double now) {
  tf_.observeClock(core::secondsToNs(now));  // after a jump too: the clock's time line decides then
  if (!clock_ || now + kClockJump >= *clock_) {
    clock_ = std::max(now, clock_.value_or(now));
    // The marks of a past jump expire once the clock has run on past them.
    if (clock_follows_tf_ && *clock_ > tf_jump_clock_ + 2 * kClockJump)
      clock_follows_tf_ = false;
    if (tf_follows_clock_ && *clock_ > clock_jump_clock_ + 2 * kClockJump)
      tf_follows_clock_ = false;
    return;
  }
  const double back = *clock_ - now;
  clock_ = now;
  if (clock_follows_tf_) {
    // tf went back first (counted then): the scans waiting now came on the new time line, their wait
    // measured from a clock not yet back. It starts again.
    clock_follows_tf_ = false;
    for (Pending& pending : pending_)
      pending.arrival = now;
    return;
  }
  ++counters_.time_jumps;
  report_(PipelineEvent::kTimeJump, "the clock went back " + std::to_string(back) +
                                        " s: clearing the tf cache and " + std::to_string(pending_.size()) +
                                        " waiting " + std::string(Processor::kNoun) + "s");
  tf_.forgetMotion();
  tf_began_ = 0;
  scan_line_newest_.reset();  // the scans after it start the time line tf starts on
  tf_line_ = scan_line_;
  // tf of the old time line may still be on its way (another connection) and refill the cache: the tf
  // going back after it is then this jump, not another.
  tf_follows_clock_ = true;
  clock_jump_clock_ = now;
  failWaiting("the clock went back");
}

template <class Processor>
void SweepPipeline<Processor>::failWaiting(const std::string& reason, core::TimeNs new_time_line,
                                           std::optional<std::uint64_t> keep_line) {
  std::deque<Pending> waiting;
  waiting.swap(pending_);
  for (Pending& pending : waiting) {
    if ((new_time_line != 0 && std::abs(pending.prepared.latest() - new_time_line) <= kClockJumpNs) ||
        pending.line == keep_line) {
      pending_.push_back(std::move(pending));  // stamped on the new time line: its tf is coming
    } else if (!tf_.mountKnown(pending.frame))
      dropForMount(pending, "");
    else
      fail(pending, kCauseTimeJump, reason);
  }
}

template <class Processor>
bool SweepPipeline<Processor>::onOtherLine(const Pending& pending, core::TimeNs newest) const {
  return waiting_ == Waiting::kRecording && pending.line > tf_line_ && newest != 0 &&
         pending.prepared.latest() + kClockJumpNs < newest &&
         pending.prepared.earliest() + TfFeed::kFarNs >= newest;
}

template <class Processor>
void SweepPipeline<Processor>::noteScanLine(Pending& pending) {
  const core::TimeNs latest = pending.prepared.latest();
  const core::TimeNs newest = tf_.newestChainTime();
  if (newest == 0 || std::abs(latest - newest) <= TfFeed::kFarNs) {  // else a stamp tf cannot take
    if (scan_line_newest_ && latest + kClockJumpNs < *scan_line_newest_) {
      ++scan_line_;  // the stamps went back: a recording whose clock restarts, or one scan stamped back
      scan_line_newest_ = latest;
    } else {
      scan_line_newest_ = std::max(latest, scan_line_newest_.value_or(latest));
    }
  }
  pending.line = scan_line_;
}

template <class Processor>
void SweepPipeline<Processor>::addTransforms(const std::vector<geometry_msgs::TransformStamped>& transforms,
                                             bool is_static, double now) {
  observeClock(now);
  for (const geometry_msgs::TransformStamped& transform : transforms)
    tf_.add(transform, is_static);
  if (tf_began_ == 0)
    tf_began_ = tf_.newestChainTime();
  serveReady(now);
}

template <class Processor>
void SweepPipeline<Processor>::add(const typename Message::ConstPtr& message, double now, std::uint64_t id) {
  observeClock(now);
  ++counters_.received;
  // A gap in header.seq is scans lost upstream; a smaller seq is a restarted driver or a looped bag,
  // and 0 is taken for "unset". A repeated seq (ROS 2 conversions write 0 for all, some drivers
  // repeat theirs) numbers no scans: nothing counts until seq goes up by one again.
  const std::uint32_t seq = message->header.seq;
  if (last_seq_ && seq == *last_seq_)
    seq_repeated_ = true;
  else if (last_seq_ && seq == *last_seq_ + 1)
    seq_repeated_ = false;
  if (last_seq_ && !seq_repeated_ && *last_seq_ != 0 && seq > *last_seq_ + 1 &&
      seq - *last_seq_ <= kMaxSeqGap)
    counters_.lost_upstream += seq - *last_seq_ - 1;
  last_seq_ = seq;
  Pending pending;
  pending.arrival = now;
  pending.id = id;
  try {
    pending.prepared = processor_.prepare(message);
  } catch (const std::exception& error) {  // core::InvalidInput, or out of memory for an absurd scan
    ++counters_.dropped_invalid;
    ++counters_.dropped_by_cause[kCauseMalformed];
    report_(PipelineEvent::kMalformed,
            "dropping malformed " + std::string(Processor::kNoun) + " (frame '" + message->header.frame_id +
                "', stamp " + std::to_string(message->header.stamp.toSec()) + "): " + error.what());
    return;
  }
  pending.frame = normalizedFrame(message->header.frame_id);
  if (message->header.stamp.isZero()) {
    ++counters_.dropped_by_cause[kCauseStampUnset];
    dropInvalid(pending, "header.stamp is 0 (unset: the driver did not stamp it)");
    return;
  }
  if (waiting_ == Waiting::kRecording)  // the scans' time lines serve the offline wait only (onOtherLine):
    noteScanLine(pending);              // live, no tf lookup per scan for them; before tf may jump onto it
  tf_.observeSweep(pending.prepared.latest());  // the time line tf must serve
  if (pending.line != tf_line_ && !tf_.jumpPending()) {
    // A time line of the scans reaching tf's newest is tf's (one scan stamped back, then the stream
    // going on as before); far behind it, the scans on it wait for tf's jump (onOtherLine).
    const core::TimeNs newest = tf_.newestChainTime();
    if (newest == 0 || pending.prepared.latest() + kClockJumpNs >= newest)
      tf_line_ = pending.line;
  }
  const char* fallback = pending.prepared.timingFallback();
  if (fallback != nullptr && counters_.time_fallbacks++ == 0)
    report_(PipelineEvent::kTimeFallback, std::string(fallback) + " (counted)");
  if (std::string found = pending.prepared.timingFound(); !found.empty() && found != timing_found_) {
    timing_found_ = std::move(found);
    report_(PipelineEvent::kTimingFound, timing_found_);
  }
  pending_.push_back(std::move(pending));
  // A recording's scans wait for tf that comes late without a count: tf decides each one.
  while (waiting_ == Waiting::kTimeout && static_cast<int>(pending_.size()) > params_.queue_size) {
    ++counters_.dropped_queue;
    ++counters_.dropped_by_cause[kCauseQueue];
    report_(PipelineEvent::kQueueFull, "more than " + std::to_string(params_.queue_size) + " " +
                                           std::string(Processor::kNoun) + "s wait for tf; dropping the oldest" +
                                           queueAdvice());
    pending_.pop_front();
  }
  serveReady(now);
}

template <class Processor>
std::string SweepPipeline<Processor>::queueAdvice() const {
  // Every scan waits at least the look-ahead: the queue must hold the scans that arrive meanwhile, plus
  // the one arriving and one for tf's sample period.
  const double look_ahead = core::nsToSeconds(lookAheadNs());
  const double span = pending_.back().arrival - pending_.front().arrival;
  if (!(look_ahead > 0.0) || pending_.size() < 2 || !(span > 0.0) || span >= look_ahead)
    return "";
  const double rate = static_cast<double>(pending_.size() - 1) / span;
  const double needed = std::ceil(rate * look_ahead - 1e-3) + 2.0;  // (the rate is measured: not 40.0001 Hz)
  return ": each waits fit_look_ahead (" + formatNumber(look_ahead) + " s), at " + formatNumber(rate) +
         " Hz queue_size must be " + formatNumber(needed) + " or more";
}

template <class Processor>
bool SweepPipeline<Processor>::extrapolatable(const Pending& pending) const {
  if (params_.max_extrapolation <= 0.0 || !tf_.mountKnown(pending.frame))
    return false;
  const core::TimeNs first = pending.prepared.earliest();
  const core::TimeNs last = pending.prepared.latest();
  if (!tf_.covers(first, first))
    return false;
  // tf of the chain ends inside the sweep, less than max_extrapolation before its last beam.
  const core::TimeNs newest = tf_.newestChainTime();
  return newest >= first && newest + core::secondsToNs(params_.max_extrapolation) >= last;
}

template <class Processor>
void SweepPipeline<Processor>::serveReady(double now) {
  observeClock(now);
  if (waiting_ == Waiting::kRecording) {
    serveRecorded(now);
    return;
  }
  while (!pending_.empty()) {
    if (tf_.jumpPending())
      return;  // tf went back: a time jump or stale tf, told by the transforms that follow
    const Pending& front = pending_.front();
    std::string never;
    const Coverage coverage = tf_.coverage(front.prepared.earliest(), front.prepared.latest(), &never);
    // The mount may arrive after the motion (another connection): wait for both, and for tf to pass the
    // sweep's end by the twist fit's look-ahead (fit_look_ahead; expire() serves it with what there is
    // at tf_timeout). tf only grows: later scans wait too.
    if (coverage == Coverage::kNotYet ||
        (coverage == Coverage::kCovered &&
         (!tf_.mountKnown(front.frame) ||
          (lookAheadNs() > 0 && tf_.newestChainTime() < front.prepared.latest() + lookAheadNs()))))
      return;
    const Pending next = std::move(pending_.front());
    pending_.pop_front();
    if (coverage == Coverage::kNever) {
      ++counters_.dropped_by_cause[kCauseStamp];
      dropInvalid(next, never);  // tf cannot take its times: never at the head of the queue
    } else {
      correct(next, false, now);
    }
  }
}

template <class Processor>
void SweepPipeline<Processor>::serveRecorded(double now) {
  if (tf_.jumpPending())
    return;  // tf went back: a time jump or stale tf, told by the transforms that follow
  // tf only grows: a sweep ending after tf's newest waits, and with a look-ahead of the twist fit
  // (fit_look_ahead) until tf passes its end by that much, so that the fit reads the same samples
  // however the recording interleaves tf and scans (flush() serves with what there is). Once tf has
  // passed its end, tf either covers it or never will (its start before tf began, or gone from the cache).
  const core::TimeNs newest = tf_.newestChainTime();
  const core::TimeNs look_ahead = lookAheadNs();
  std::map<std::string, bool> mount_known;  // by frame, for this call
  for (auto it = pending_.begin(); it != pending_.end();) {
    const core::TimeNs latest = it->prepared.latest();
    if (newest == 0 || (latest + look_ahead > newest && latest <= newest + TfFeed::kFarNs) ||
        onOtherLine(*it, newest)) {
      ++it;  // tf's newest on an old time line would serve it from that one's cache
      continue;
    }
    std::string never;
    const Coverage coverage =
        it->covered ? Coverage::kCovered : tf_.coverage(it->prepared.earliest(), latest, &never);
    const auto known = mount_known.try_emplace(it->frame, false);
    if (known.second)
      known.first->second = tf_.mountKnown(it->frame);
    if (coverage == Coverage::kCovered && !known.first->second) {
      it->covered = true;  // tf only grows: not asked again while it waits for the mount
      ++it;                // the mount may come later (another connection)
      continue;
    }
    const Pending next = std::move(*it);
    it = pending_.erase(it);
    if (coverage == Coverage::kNever) {
      ++counters_.dropped_by_cause[kCauseStamp];
      dropInvalid(next, never);
    } else if (coverage == Coverage::kCovered) {
      correct(next, false, now);
    } else {
      failNotCovered(next, "");
    }
  }
}

template <class Processor>
std::string SweepPipeline<Processor>::whyNotCovered(const Pending& pending) const {
  if (tf_.jumpPending())
    return "tf " + tf_.fixedFrame() + " -> " + tf_.baseFrame() +
           " went back in time: a time jump or stale tf, not yet told apart";
  const core::TimeNs newest = tf_.newestChainTime();
  if (onOtherLine(pending, newest)) {
    return "tf " + tf_.fixedFrame() + " -> " + tf_.baseFrame() + " stayed on another time line: the scans' " +
           "stamps went back by more than " + formatNumber(kClockJump) + " s (a recording whose clock " +
           "restarts?) and tf did not follow; its newest lies " +
           formatNumber(core::nsToSeconds(newest - pending.prepared.latest())) + " s after the sweep's end";
  }
  return tf_.whyNotCovered(pending.prepared.earliest(), pending.prepared.latest(),
                           core::secondsToNs(pending.arrival));
}

template <class Processor>
std::string SweepPipeline<Processor>::causeNotCovered(const Pending& pending) const {
  if (tf_.jumpPending())
    return kCauseUndecided;
  const core::TimeNs newest = tf_.newestChainTime();
  if (newest == 0)
    return "no tf " + tf_.fixedFrame() + " -> " + tf_.baseFrame();
  if (onOtherLine(pending, newest))
    return kCauseOtherLine;
  if (newest < pending.prepared.latest())
    return waiting_ == Waiting::kRecording ? kCauseEnd : kCauseEndLive;
  return pending.prepared.earliest() < tf_began_ ? kCauseBegan : kCauseStart;
}

template <class Processor>
void SweepPipeline<Processor>::failNotCovered(const Pending& pending, const std::string& suffix) {
  fail(pending, causeNotCovered(pending), whyNotCovered(pending) + suffix);
}

template <class Processor>
void SweepPipeline<Processor>::dropInvalid(const Pending& pending, const std::string& why) {
  ++counters_.dropped_invalid;
  report_(PipelineEvent::kMalformed,
          "dropping " + std::string(Processor::kNoun) + " (frame '" + pending.frame + "', stamp " +
              std::to_string(pending.prepared.message->header.stamp.toSec()) + "): invalid stamp: " + why);
}

template <class Processor>
void SweepPipeline<Processor>::dropForMount(const Pending& pending, const std::string& error) {
  ++counters_.dropped_mount;
  ++counters_.dropped_by_cause[kCauseMount];
  report_(PipelineEvent::kMountMissing,
          "dropping " + std::string(Processor::kNoun) + " at " +
              std::to_string(pending.prepared.message->header.stamp.toSec()) + ": no transform " +
              tf_.baseFrame() + " -> " + pending.frame +
              " (the laser mount): " + (error.empty() ? tf_.whyNoMount(pending.frame) : error));
}

template <class Processor>
void SweepPipeline<Processor>::expire(double now) {
  serveReady(now);
  // Scans wait in arrival order: the front one has waited longest.
  const double longest = longestWait();
  while (!pending_.empty() && now - pending_.front().arrival > longest) {
    const Pending expired = std::move(pending_.front());
    pending_.pop_front();
    if (coveredWithoutLookAhead(expired)) {
      correct(expired, false, now);  // tf stopped short of the look-ahead: served with what there is
    } else if (extrapolatable(expired)) {
      // The wait is over (tf_timeout, the latency budget): extrapolate rather than fail.
      correct(expired, true, now);
    } else if (!tf_.mountKnown(expired.frame)) {
      dropForMount(expired, "");
    } else {
      failNotCovered(expired, waiting_ == Waiting::kRecording
                                  ? " (waited " + formatNumber(longest) + " s of record time)"
                                  : " (waited tf_timeout, " + formatNumber(longest) + " s)");
    }
    serveReady(now);  // scans behind an expired one may be ready: serve them before they expire
  }
}

template <class Processor>
core::TimeNs SweepPipeline<Processor>::lookAheadNs() const {
  return params_.deskew.interpolation == core::Interpolation::kTwist ? core::secondsToNs(params_.deskew.fit_look_ahead)
                                                                     : 0;
}

template <class Processor>
bool SweepPipeline<Processor>::coveredWithoutLookAhead(const Pending& pending) const {
  if (lookAheadNs() == 0)
    return false;
  const core::TimeNs newest = tf_.newestChainTime();
  return newest >= pending.prepared.latest() && !onOtherLine(pending, newest) &&
         tf_.mountKnown(pending.frame) &&
         tf_.coverage(pending.prepared.earliest(), pending.prepared.latest(), nullptr) == Coverage::kCovered;
}

template <class Processor>
void SweepPipeline<Processor>::flush() {
  std::deque<Pending> waiting;
  waiting.swap(pending_);
  const core::TimeNs newest = tf_.newestChainTime();
  for (const Pending& pending : waiting) {
    std::string never;
    const Coverage coverage = tf_.coverage(pending.prepared.earliest(), pending.prepared.latest(), &never);
    if (coverage == Coverage::kNever) {
      ++counters_.dropped_by_cause[kCauseStamp];
      dropInvalid(pending, never);
    } else if (!tf_.mountKnown(pending.frame)) {
      dropForMount(pending, "");
    } else if (onOtherLine(pending, newest)) {
      failNotCovered(pending, "");  // tf's cache may cover it, from another time line
    } else if (coverage == Coverage::kCovered) {
      correct(pending, false, clock_.value_or(pending.arrival));  // tf that went back undecided is not in it
    } else {
      failNotCovered(pending, "");
    }
  }
}

template <class Processor>
void SweepPipeline<Processor>::correct(const Pending& pending, bool extrapolate, double now) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  // The mount in force at the sweep's end: a re-published /tf_static serves the sweeps ending at or after
  // its stamp, not those that waited for tf while it arrived.
  const std::optional<mrpt::poses::CPose3D> mount =
      tf_.mount(pending.frame, pending.prepared.latest(), error);
  if (!mount) {
    dropForMount(pending, error);
    return;
  }
  Result result;
  try {
    if (extrapolate) {
      std::vector<core::TimeNs> samples;
      const core::TimeNs newest = tf_.newestChainTime();
      tf_.motion().appendSampleTimes(newest - 1'000'000'000, newest, samples);
      const core::TimeNs previous = samples.empty() ? newest : samples.back();
      const ExtrapolatingMotion motion(tf_.motion(), newest, previous,
                                       newest + core::secondsToNs(params_.max_extrapolation));
      result.outputs = processor_.correct(pending.prepared, *mount, motion);
      ++counters_.extrapolated;
    } else {
      result.outputs = processor_.correct(pending.prepared, *mount, tf_.motion());
    }
  } catch (const TfGapTooLong& gap) {
    ++counters_.tf_gaps;
    fail(pending, kCauseTfGap, gap.what());
    return;
  } catch (const core::MotionUnavailable& unavailable) {
    fail(pending, kCauseMotion, unavailable.what());
    return;
  }
  ++counters_.published;
  result.corrected = true;
  result.id = pending.id;
  result.waited = std::max(0.0, now - pending.arrival);
  result.correction = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  publish_(result);
  if (corrected_ && !extrapolate)
    corrected_(pending.prepared, *mount);
}

template <class Processor>
void SweepPipeline<Processor>::fail(const Pending& pending, const std::string& cause,
                                    const std::string& reason) {
  const std::string stamp = std::to_string(pending.prepared.message->header.stamp.toSec());
  if (params_.on_tf_failure == OnTfFailure::kDrop) {
    ++counters_.dropped_tf;
    ++counters_.dropped_by_cause[cause];
    report_(PipelineEvent::kTfFailure, "dropping " + std::string(Processor::kNoun) + " at " + stamp +
                                           " (frame " + pending.frame + "): " + reason);
    return;
  }
  ++counters_.passed_through;
  ++counters_.passed_by_cause[cause];
  report_(PipelineEvent::kTfFailure, "passing " + std::string(Processor::kNoun) + " at " + stamp +
                                         " (frame " + pending.frame + ") through uncorrected: " + reason);
  Result result;
  result.outputs = processor_.passThrough(pending.prepared);
  result.id = pending.id;
  publish_(result);
}

template class SweepPipeline<ScanProcessor>;
template class SweepPipeline<CloudProcessor>;

}  // namespace lidar_deskew::ros_adapter
