// The one tf policy of the live node and deskew_bag (docs/DESIGN.md §3): which transforms
// go into the buffer, when time went backwards, and which mount serves a scan.
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <mrpt/poses/CPose3D.h>
#include <tf2/buffer_core.h>

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "lidar_deskew/core/types.h"
#include "lidar_deskew/ros/tf_motion.h"

namespace lidar_deskew::ros_adapter {

/// What the feed tells its owner (who logs and counts it).
enum class TfEvent {
  kStaticIgnored,  ///< a /tf_static parent of a frame that moves on /tf was left out (once per frame)
  kTimeJump,       ///< a link's stamps went back by more than 1 s and went on so: the tf cache was cleared
  kStaleIgnored,   ///< a transform stamped over 1 s before its link's newest, the link's time line going on
                   ///< (a stray publisher of stale tf), or, on any dynamic link, more than the cache time
                   ///< before its frame's newest (tf2 would refuse it): left out, reported for each
  kAheadIgnored,   ///< a transform stamped over 1 s after its link's newest, off the time line of the
                   ///< sweeps (a stray publisher on a clock ahead): left out, reported for each
  kTwoParents,     ///< a frame has two parents on /tf (once per frame)
  kBadTransform,   ///< a transform refused (by tf2, or for empty or equal frames, non-finite values)
  kMountFirst,     ///< the first mount of a scan frame
  kMountChanged,   ///< the mount of a scan frame changed
};

/// Whether tf answers fixed -> base over a sweep.
enum class Coverage {
  kCovered,  ///< at both ends
  kNotYet,   ///< not now; it may later
  kNever,    ///< tf cannot take the sweep's times (0, far from tf's time line, or tf2 throws on them)
};

/// Owns the tf2 buffer that answers fixed_frame -> base_frame and the mounts. Frame ids are normalised
/// (a leading '/' dropped) everywhere. Rules, the same live and offline:
/// - A frame that is the child of a /tf (dynamic) transform moves: a /tf_static parent of it is left
///   out, whichever came first (tf2 would otherwise answer one pose for all times). Statics of frames
///   that do not move on /tf (REP-105's base_footprint -> base_link under a moving base_footprint, a
///   mount through a plate) are kept.
/// - A dynamic link of the fixed -> base chain stamped more than 1 s before or after that link's own
///   newest stamp leaves the link's time line. The time line tf must serve (timeLine(): the sweeps'
///   stamps, else the owner's clock) tells which one is real when one of the two lies within
///   kNearNs of it and closer by over kCloserNs: a transform off it is left out (stale or ahead, a
///   stray publisher on another clock), the cache kept; one on it going back is a time jump at once
///   (the cache cleared, the transform starting the new time line), going ahead is taken. When it
///   cannot tell (no sweep, a clock on another time line), a transform going back is held back: when
///   the new, earlier time line goes on (kJumpConfirmations such transforms of the link in a row)
///   time went backwards (a bag loop, a /clock reset): the dynamic cache is cleared and the held
///   transforms start the new time line. When the old time line goes on instead, the held ones were
///   stale: left out, the cache kept.
/// - A frame with two parents on /tf (map -> base_link beside odom -> base_link) is reported.
/// - tf2's exceptions (its own, and ros::Time's "out of dual 32-bit range" for far stamps) are caught
///   here: a transform refused, a time tf cannot take.
/// - Transforms tf2 refuses (or that have empty or equal frame ids, non-finite values) are reported
///   and leave no trace.
/// - The mount base_frame -> scan frame (any chain, identity when the scan frame is the base frame) is
///   the one in force at the sweep's end: each /tf_static publication of a link is kept with its stamp
///   and holds from that stamp until the next publication's (the first one also before its stamp, so
///   a static stamped 0, or a mount arriving late, serves every sweep); a link on /tf is looked up at
///   the sweep's end (its newest when tf has not reached that yet). A publication supersedes the
///   link's publications stamped at or after its own stamp (a re-sent static stamped 0 replaces them
///   all). The last mount used is kept when a time jump clears the dynamic tf.
/// Not thread-safe.
class TfFeed {
 public:
  using Notify = std::function<void(TfEvent, const std::string&)>;

  /// `cache_time` [s]: how much dynamic tf history is kept.
  TfFeed(const std::string& fixed_frame, const std::string& base_frame, double cache_time, Notify notify);
  TfFeed(const TfFeed&) = delete;
  TfFeed& operator=(const TfFeed&) = delete;

  /// Adds one transform from /tf (is_static false) or /tf_static. Returns false when time went
  /// backwards and the dynamic cache was cleared before this transform was added.
  bool add(const geometry_msgs::TransformStamped& transform, bool is_static);

  /// Clears the dynamic tf (statics and the mounts seen stay): time went backwards on the owner's clock.
  /// The next /tf is then taken as the new time line, not as a jump; the sweeps' time line is forgotten
  /// until the next sweep (the clock decides meanwhile).
  void forgetMotion();

  /// The owner's clock [ns] (record time offline; ROS time live, simulated or not), at every call.
  /// Until a sweep is seen it is the time line tf must serve; after, it carries the newest sweep's
  /// time on by the time elapsed on it.
  void observeClock(core::TimeNs now);
  /// A sweep's latest time [ns] (on its stamps' clock), at its arrival: the time line tf must serve.
  /// Ignored when it lies more than kFarNs from tf's newest (an uninitialised stamp). Transforms left
  /// out as off the time line that are on it now are taken back: going back, as a time jump (the cache
  /// cleared, kTimeJump); going ahead, as the link's time line going on.
  void observeSweep(core::TimeNs latest);
  /// [ns] The time line tf must serve now: the newest sweep's latest time carried on by the owner's
  /// clock since it arrived, else the owner's clock; nullopt when neither was given.
  std::optional<core::TimeNs> timeLine() const;

  /// Transforms of a link going back in a row that make a time jump (fewer are held back undecided).
  static constexpr int kJumpConfirmations = 3;
  /// [ns] A sweep further than this from tf's newest time (either way) is never waited for: a clock
  /// mix-up or an uninitialised stamp, not late tf.
  static constexpr core::TimeNs kFarNs = 86'400'000'000'000;
  /// [ns] A time line within this of timeLine() may be the one tf must serve (a scan's latest beam lies
  /// near the real tf's newest: within tf's latency or the driver's). Further, it tells nothing: a
  /// stray publisher's stale tf of before a bag loop may lie closer to the new scans than the old line.
  static constexpr core::TimeNs kNearNs = 2'000'000'000;
  /// [ns] Of two time lines of a link, the one closer to timeLine() by more than this is the real one.
  static constexpr core::TimeNs kCloserNs = 500'000'000;

  /// True when tf answers fixed -> base at both times [ns].
  bool covers(core::TimeNs first, core::TimeNs last) const {
    return coverage(first, last) == Coverage::kCovered;
  }
  /// Whether tf answers fixed -> base at both times [ns]; for kNever, `why` (when given) says why.
  /// Never throws.
  Coverage coverage(core::TimeNs first, core::TimeNs last, std::string* why = nullptr) const;
  /// Why tf does not answer fixed -> base over [first, last] [ns], naming the frames and the cause: a
  /// frame unknown to tf (with the closest known name), a frame with two parents, the frames not
  /// connected, tf short of the sweep's end (by how much; when the sweep ends after `arrival` [ns, on the
  /// stamps' clock], a driver stamping late), tf no longer holding the sweep's start.
  std::string whyNotCovered(core::TimeNs first, core::TimeNs last, core::TimeNs arrival) const;
  /// Why there is no mount base_frame -> `frame` (normalised): the frame unknown to tf (with the closest
  /// known name) or not connected to the base.
  std::string whyNoMount(const std::string& frame) const;
  /// Why tf has no fixed -> base at all (empty when it has): a frame unknown to tf (with the closest
  /// known name), or the frames not connected, with tf's frames listed.
  std::string whyNoChain() const;
  /// [ns] The stamp of the transform that started the new time line at the last time jump (0: none).
  core::TimeNs jumpedTo() const { return jumped_to_; }
  /// True while a link's stamps went back and it is not yet told whether time jumped or the
  /// transforms were stale.
  bool jumpPending() const { return !backward_.empty(); }
  /// [ns] The newest time tf answers fixed -> base at; 0 when it answers none.
  core::TimeNs newestChainTime() const;
  /// True when a mount for `frame` (normalised) is known or tf has one.
  bool mountKnown(const std::string& frame) const;
  /// The mount of `frame` (normalised) in force at `time` [ns] (the sweep's end; 0: the newest),
  /// reporting the first one and changes; nullopt with `error` set when tf has none. No allocation
  /// when the mount's links are all static.
  std::optional<mrpt::poses::CPose3D> mount(const std::string& frame, core::TimeNs time, std::string& error);
  /// The newest mount of `frame`: mount(frame, 0, error).
  std::optional<mrpt::poses::CPose3D> mount(const std::string& frame, std::string& error) {
    return mount(frame, 0, error);
  }

  const TfMotionSource& motion() const { return motion_; }
  const tf2::BufferCore& buffer() const { return *buffer_; }
  /// For readers that take a mutable buffer (laser_geometry); add transforms through add() only.
  tf2::BufferCore& buffer() { return *buffer_; }
  const std::string& fixedFrame() const { return fixed_frame_; }
  /// [s] How much dynamic tf history is kept.
  double cacheTime() const { return cache_time_.toSec(); }
  const std::string& baseFrame() const { return base_frame_; }

 private:
  void rebuildWithout(const std::string& child);
  /// Records child's parent; the chain is walked again only when the tree changed.
  void setParent(const std::string& child, const std::string& parent);
  std::set<std::string> chainChildren() const;
  /// The chain's frames changed: chain_ and the one-link chain (planChain) again.
  void chainChanged();
  /// Hands the motion source the walk fixed -> base when it crosses one dynamic link (OneLinkChain),
  /// else none.
  void planChain();
  void notify(TfEvent event, const std::string& text) const;
  /// `what` ('fixed_frame', 'the scan frame') is unknown to tf: the text naming it, the closest known
  /// frame and tf's frames.
  std::string unknownFrame(const std::string& frame, const std::string& what) const;
  /// unknownFrame() of fixed_frame, else of base_frame, when tf does not know it; "" when it knows both.
  std::string unknownChainFrame() const;
  std::vector<std::string> sortedFrames() const;  ///< tf's frames, sorted
  std::string frameList() const;                  ///< "a, b, c" (sortedFrames), or "none"
  /// One /tf_static publication of a link.
  struct StaticLink {
    core::TimeNs stamp = 0;  ///< [ns] in force from here until the next publication's stamp
    geometry_msgs::TransformStamped transform;  ///< as given (frames normalised)
    mrpt::poses::CPose3D pose;                  ///< the child in the parent
  };
  enum class Link { kRoot, kFound, kFailed };
  /// The link above `child` at `time` [ns] (0: the newest): its parent and the child's pose in it.
  Link linkAt(const std::string& child, core::TimeNs time, const std::string*& parent,
              mrpt::poses::CPose3D& pose) const;
  /// The pose of `frame` in base_frame at `time` [ns] from the links' histories; false when they do not
  /// connect the two (or a /tf link has nothing).
  bool mountAt(const std::string& frame, core::TimeNs time, mrpt::poses::CPose3D& mount) const;
  /// Records a /tf_static publication in its child's history.
  void recordStatic(const geometry_msgs::TransformStamped& transform);
  /// Adds a dynamic transform of the chain's link `child` that went back by more than 1 s; returns
  /// false when it confirmed a time jump.
  bool holdBackward(const geometry_msgs::TransformStamped& transform);
  /// Which of a link's two time lines, its newest `newest` and a transform's `stamp` [ns] more than 1 s
  /// apart, timeLine() says is real.
  enum class Verdict { kOld, kNew, kUndecided };
  Verdict judge(core::TimeNs newest, core::TimeNs stamp) const;
  /// Clears the dynamic tf and starts the new time line with `first` (when given), then the held
  /// transforms.
  void clearMotion(const geometry_msgs::TransformStamped* first);
  /// The transforms left out that the time line now says are real (each judged against its link's
  /// newest stamp); left_out_ is emptied.
  std::vector<geometry_msgs::TransformStamped> takeBackLeftOut();
  /// Leaves out a transform off the time line (stale or ahead of its link's `newest` [ns]), reported.
  void leaveOut(const geometry_msgs::TransformStamped& transform, core::TimeNs newest);
  /// What timeLine() follows: "the scans' stamps" or "the clock".
  std::string timeLineName() const;
  /// The old time line of `child` went on: its held transforms were stale.
  void dropStale(const std::string& child, core::TimeNs newest);
  /// Records parent -> child from /tf; reports a second parent of `child`.
  void noteDynamicParent(const std::string& child, const std::string& parent, core::TimeNs stamp);

  std::string fixed_frame_;
  std::string base_frame_;
  ros::Duration cache_time_;
  Notify notify_;
  std::unique_ptr<tf2::BufferCore> buffer_;
  TfMotionSource motion_;
  /// child -> its /tf_static publications kept, in stamp order (the last one is tf2's).
  std::map<std::string, std::vector<StaticLink>> statics_;
  std::map<std::string, std::string> parents_;  // child -> parent, as last seen
  std::set<std::string> moving_;                // children of dynamic transforms
  std::set<std::string> chain_;  // the moving frames from base_frame up to fixed_frame (chainChildren)
  std::set<std::string> ignored_statics_;  // children whose static parent was reported left out
  std::map<std::string, core::TimeNs> newest_link_stamps_;  // [ns] by child frame, links of the chain
  std::map<std::string, mrpt::poses::CPose3D> mounts_;      // the last mount of each scan frame
  std::map<std::string, int> backward_;                     // by child: its transforms held in a row
  std::vector<geometry_msgs::TransformStamped> held_;       // the transforms going back, undecided
  std::optional<core::TimeNs> clock_;                       // [ns] the owner's clock, as last given
  std::optional<core::TimeNs> sweep_;                       // [ns] the newest sweep's latest time
  core::TimeNs clock_at_sweep_ = 0;                         // [ns] the owner's clock when it arrived
  core::TimeNs jumped_to_ = 0;  // [ns] the stamp that started the time line, at the last jump
  /// The transforms left out last (off the time line), newest last: at most kLeftOutKept.
  std::deque<geometry_msgs::TransformStamped> left_out_;
  static constexpr std::size_t kLeftOutKept = 64;
  /// By child: its parents on /tf and the newest stamp [ns] of each (two at once: reported).
  std::map<std::string, std::map<std::string, core::TimeNs>> dynamic_parents_;
  std::map<std::string, std::string> two_parents_;  // child -> "a and b", each reported once
  /// [ns] By child frame, every dynamic link: the newest stamp tf2 holds (it refuses one older by more
  /// than the cache time, with a console warning at each).
  std::map<std::string, core::TimeNs> newest_dynamic_stamps_;
};

}  // namespace lidar_deskew::ros_adapter
