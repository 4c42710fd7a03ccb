#include "lidar_deskew/ros/tf_feed.h"

#include <tf2/exceptions.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <iterator>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::ros_adapter {
namespace {

/// A jump backwards of the chain's stamps larger than this (bag loop, /clock reset) clears the cache.
constexpr core::TimeNs kTimeJumpNs = 1'000'000'000;

/// [ns] A sweep ending after its arrival by less than this (time_offset's range) was stamped late.
constexpr core::TimeNs kLateStampNs = 10'000'000'000;

bool finite(const geometry_msgs::Transform& t) {
  return std::isfinite(t.translation.x) && std::isfinite(t.translation.y) && std::isfinite(t.translation.z) &&
         std::isfinite(t.rotation.x) && std::isfinite(t.rotation.y) && std::isfinite(t.rotation.z) &&
         std::isfinite(t.rotation.w);
}

}  // namespace

TfFeed::TfFeed(const std::string& fixed_frame, const std::string& base_frame, double cache_time,
               Notify notify)
    : fixed_frame_(normalizedFrame(fixed_frame)),
      base_frame_(normalizedFrame(base_frame)),
      cache_time_(cache_time),
      notify_(std::move(notify)),
      buffer_(std::make_unique<tf2::BufferCore>(cache_time_)),
      motion_(*buffer_, fixed_frame_, base_frame_, static_cast<core::TimeNs>(cache_time_.toNSec())) {}

void TfFeed::notify(TfEvent event, const std::string& text) const {
  if (notify_)
    notify_(event, text);
}

bool TfFeed::add(const geometry_msgs::TransformStamped& transform_in, bool is_static) {
  geometry_msgs::TransformStamped transform = transform_in;
  transform.header.frame_id = normalizedFrame(transform.header.frame_id);
  transform.child_frame_id = normalizedFrame(transform.child_frame_id);
  const std::string& parent = transform.header.frame_id;
  const std::string& child = transform.child_frame_id;
  if (parent.empty() || child.empty() || parent == child || !finite(transform.transform)) {
    notify(TfEvent::kBadTransform, "ignoring a transform '" + parent + "' -> '" + child +
                                       "': empty or equal frame ids, or non-finite values");
    return true;
  }

  if (is_static) {
    if (moving_.count(child)) {
      if (ignored_statics_.insert(child).second) {
        notify(TfEvent::kStaticIgnored, "ignoring /tf_static " + parent + " -> " + child + " (" +
                                            describePose(toPose(transform.transform)) + "): " + child +
                                            " moves on /tf (from " + parents_[child] + ")");
      }
      return true;
    }
    bool taken = false;
    try {
      taken = buffer_->setTransform(transform, "tf_static", true);
    } catch (const std::exception&) {
    }
    if (!taken) {
      notify(TfEvent::kBadTransform, "tf2 refused /tf_static " + parent + " -> " + child);
      return true;
    }
    recordStatic(transform);
    setParent(child, parent);
    planChain();  // a static of the chain may have changed
    return true;
  }

  if (moving_.insert(child).second) {
    chainChanged();
    const auto kept = statics_.find(child);
    if (kept != statics_.end()) {
      ignored_statics_.insert(child);
      const StaticLink& newest = kept->second.back();
      notify(TfEvent::kStaticIgnored, "ignoring /tf_static " + newest.transform.header.frame_id + " -> " +
                                          child + " (" + describePose(newest.pose) + "): " + child +
                                          " moves on /tf (from " + parent + ", " +
                                          describePose(toPose(transform.transform)) + ")");
      rebuildWithout(child);
    }
  }
  setParent(child, parent);
  const core::TimeNs stamp = toNs(transform.header.stamp);
  const bool on_chain = chain_.count(child) > 0;
  if (on_chain) {
    // Each link against its own newest stamp: links of one chain may lag or lead each other by more
    // than a second (a localiser future-dating map -> odom), and that is no jump.
    const auto newest = newest_link_stamps_.find(child);
    if (newest != newest_link_stamps_.end() && std::abs(stamp - newest->second) > kTimeJumpNs) {
      const bool back = stamp < newest->second;
      switch (judge(newest->second, stamp)) {
        case Verdict::kOld:
          leaveOut(transform, newest->second);
          return true;
        case Verdict::kNew:
          if (back) {
            jumped_to_ = stamp;
            notify(TfEvent::kTimeJump, "time went backwards (" + parent + " -> " + child + ", " +
                                           formatNumber(core::nsToSeconds(newest->second - stamp)) +
                                           " s, onto the time line of " + timeLineName() +
                                           "): clearing the tf cache");
            clearMotion(&transform);
            return false;
          }
          break;  // ahead onto the time line: taken
        case Verdict::kUndecided:
          if (back)
            return holdBackward(transform);
          break;
      }
    }
    if (backward_.count(child) > 0)
      dropStale(child, stamp);
  }
  // tf2 refuses a transform stamped more than the cache time before its frame's newest, and says so on
  // the console at each one (TF_OLD_DATA): a stray publisher of stale tf, left out here and said once.
  const auto held = newest_dynamic_stamps_.find(child);
  if (held != newest_dynamic_stamps_.end() && stamp + cache_time_.toNSec() < held->second) {
    notify(TfEvent::kStaleIgnored, "ignoring /tf " + parent + " -> " + child + " stamped " +
                                       formatNumber(core::nsToSeconds(held->second - stamp)) +
                                       " s before the frame's newest, more than the tf cache keeps (" +
                                       formatNumber(cacheTime()) + " s): stale tf from another publisher?");
    return true;
  }
  bool taken = false;
  std::string refusal;
  try {
    taken = buffer_->setTransform(transform, "tf", false);
  } catch (const std::exception& error) {  // a stamp within the cache time of ros::Time's end (2106)
    refusal = std::string(": ") + error.what();
  }
  if (!taken) {  // no trace: the link's newest stamp, its parents and the knots stay as they were
    notify(TfEvent::kBadTransform, "tf2 refused /tf " + parent + " -> " + child + " at " +
                                       std::to_string(transform.header.stamp.toSec()) + refusal);
    return true;
  }
  noteDynamicParent(child, parent, stamp);
  core::TimeNs& frame_newest = newest_dynamic_stamps_[child];
  frame_newest = std::max(frame_newest, stamp);
  if (on_chain) {
    core::TimeNs& newest_stamp = newest_link_stamps_[child];
    newest_stamp = std::max(newest_stamp, stamp);
    motion_.addSampleTime(stamp);
    // One dynamic link straight from fixed to base: its stamps are all of the chain's samples.
    motion_.setSingleLink(chain_.size() == 1 && parent == fixed_frame_ && child == base_frame_);
  }
  motion_.chain().add(child, parent, stamp, transform.transform);  // its own link's only
  if (child == fixed_frame_)
    motion_.chain().addFixedLinkStamp(stamp);  // a localiser's map -> odom
  return true;
}

TfFeed::Verdict TfFeed::judge(core::TimeNs newest, core::TimeNs stamp) const {
  const std::optional<core::TimeNs> line = timeLine();
  if (!line)
    return Verdict::kUndecided;
  const core::TimeNs to_old = std::abs(newest - *line), to_new = std::abs(stamp - *line);
  if (to_old <= kNearNs && to_old + kCloserNs < to_new)
    return Verdict::kOld;
  if (to_new <= kNearNs && to_new + kCloserNs < to_old)
    return Verdict::kNew;
  return Verdict::kUndecided;  // a clock on another time line, or both as near
}

std::string TfFeed::timeLineName() const {
  return sweep_ ? "the scans' stamps" : "the clock";
}

void TfFeed::leaveOut(const geometry_msgs::TransformStamped& transform, core::TimeNs newest) {
  const core::TimeNs stamp = toNs(transform.header.stamp);
  left_out_.push_back(transform);
  if (left_out_.size() > kLeftOutKept)
    left_out_.pop_front();
  const bool back = stamp < newest;
  const core::TimeNs off = std::abs(stamp - timeLine().value_or(newest));
  notify(back ? TfEvent::kStaleIgnored : TfEvent::kAheadIgnored,
         "ignoring /tf " + transform.header.frame_id + " -> " + transform.child_frame_id + " stamped " +
             formatNumber(core::nsToSeconds(std::abs(newest - stamp))) + " s " + (back ? "before" : "after") +
             " the link's newest, " + formatNumber(core::nsToSeconds(off)) + " s off the time line of " +
             timeLineName() + ": " + (back ? "stale tf" : "tf ahead") +
             " from another publisher? (on another clock)");
}

void TfFeed::observeClock(core::TimeNs now) {
  clock_ = now;
}

void TfFeed::observeSweep(core::TimeNs latest) {
  const core::TimeNs newest = newestChainTime();
  if (newest != 0 && std::abs(latest - newest) > kFarNs)
    return;  // an uninitialised stamp, never served: no time line
  sweep_ = latest;
  clock_at_sweep_ = clock_.value_or(0);
  // The time line moved (a bag loop, a test rig starting a new time line): transforms left out as off
  // the old one may be on it. Going back, that is a time jump, seen now, not at the next transform (the
  // sweep may wait for tf that already came).
  core::TimeNs back_to = 0;
  std::string link;
  for (const geometry_msgs::TransformStamped& transform : left_out_) {
    const auto link_newest = newest_link_stamps_.find(transform.child_frame_id);
    const core::TimeNs stamp = toNs(transform.header.stamp);
    if (link_newest != newest_link_stamps_.end() && stamp < link_newest->second &&
        judge(link_newest->second, stamp) == Verdict::kNew && (back_to == 0 || stamp < back_to)) {
      back_to = stamp;
      link = transform.header.frame_id + " -> " + transform.child_frame_id + ", " +
             formatNumber(core::nsToSeconds(link_newest->second - stamp)) + " s";
    }
  }
  if (back_to != 0) {
    jumped_to_ = back_to;
    notify(TfEvent::kTimeJump, "time went backwards (" + link + ", onto the time line of " + timeLineName() +
                                   "): clearing the tf cache");
    clearMotion(nullptr);
    return;
  }
  // Ahead: taken as the link's time line going on.
  for (geometry_msgs::TransformStamped& transform : takeBackLeftOut())
    add(transform, false);
}

std::optional<core::TimeNs> TfFeed::timeLine() const {
  if (sweep_)
    return *sweep_ + (clock_ ? std::max<core::TimeNs>(0, *clock_ - clock_at_sweep_) : 0);
  return clock_;
}

bool TfFeed::holdBackward(const geometry_msgs::TransformStamped& transform) {
  const std::string& child = transform.child_frame_id;
  held_.push_back(transform);
  const int in_a_row = ++backward_[child];
  if (in_a_row < kJumpConfirmations)
    return true;  // undecided: the old time line may still go on (a stray publisher of stale tf)
  const core::TimeNs back = newest_link_stamps_[child] - toNs(transform.header.stamp);
  jumped_to_ = toNs(held_.front().header.stamp);
  notify(TfEvent::kTimeJump, "time went backwards (" + transform.header.frame_id + " -> " + child + ", " +
                                 formatNumber(core::nsToSeconds(back)) + " s, " + std::to_string(in_a_row) +
                                 " transforms in a row): clearing the tf cache");
  clearMotion(nullptr);  // takes the held transforms again: they start the new time line
  return false;
}

void TfFeed::dropStale(const std::string& child, core::TimeNs newest) {
  std::vector<geometry_msgs::TransformStamped> stale;
  const auto of_child = [&](const geometry_msgs::TransformStamped& t) { return t.child_frame_id == child; };
  std::copy_if(held_.begin(), held_.end(), std::back_inserter(stale), of_child);
  held_.erase(std::remove_if(held_.begin(), held_.end(), of_child), held_.end());
  backward_.erase(child);
  for (const geometry_msgs::TransformStamped& transform : stale) {
    notify(TfEvent::kStaleIgnored,
           "ignoring /tf " + transform.header.frame_id + " -> " + child + " stamped " +
               formatNumber(core::nsToSeconds(newest - toNs(transform.header.stamp))) +
               " s before the link's newest, whose time line goes on: stale tf from another publisher?");
  }
}

void TfFeed::noteDynamicParent(const std::string& child, const std::string& parent, core::TimeNs stamp) {
  std::map<std::string, core::TimeNs>& parents = dynamic_parents_[child];
  core::TimeNs& newest = parents[parent];
  newest = std::max(newest, stamp);
  if (parents.size() < 2 || two_parents_.count(child) > 0)
    return;
  const core::TimeNs cache = cache_time_.toNSec();
  for (const auto& [other, other_stamp] : parents) {
    if (other == parent || std::abs(other_stamp - stamp) > cache)
      continue;  // a re-parenting long ago is no second parent
    two_parents_[child] = other + " and " + parent;
    notify(TfEvent::kTwoParents, child + " has two parents on /tf, " + two_parents_[child] +
                                     " (two publishers of " + child + "?): tf answers through whichever " +
                                     "came last, so lookups through " + child + " fail or jump");
    return;
  }
}

void TfFeed::forgetMotion() {
  sweep_.reset();  // the sweeps' time line went with the clock: the clock decides until the next sweep
  clearMotion(nullptr);
}

void TfFeed::clearMotion(const geometry_msgs::TransformStamped* first) {
  // The transforms left out as off the old time line that the time line now says are real (the new
  // one's that came before its first sweep) start it with `first`, in stamp order.
  std::vector<geometry_msgs::TransformStamped> starting = takeBackLeftOut();
  if (first)
    starting.push_back(*first);
  std::stable_sort(starting.begin(), starting.end(),
                   [](const auto& a, const auto& b) { return a.header.stamp < b.header.stamp; });
  buffer_->clear();
  motion_.clearSamples();
  newest_link_stamps_.clear();
  newest_dynamic_stamps_.clear();
  dynamic_parents_.clear();
  backward_.clear();
  // The held transforms went back with the time: they are on the new time line too (each judged again).
  std::vector<geometry_msgs::TransformStamped> held;
  held.swap(held_);
  for (const geometry_msgs::TransformStamped& transform : starting)
    add(transform, false);
  for (const geometry_msgs::TransformStamped& transform : held)
    add(transform, false);
}

std::vector<geometry_msgs::TransformStamped> TfFeed::takeBackLeftOut() {
  std::vector<geometry_msgs::TransformStamped> real;
  for (const geometry_msgs::TransformStamped& transform : left_out_) {
    const auto newest = newest_link_stamps_.find(transform.child_frame_id);
    if (newest != newest_link_stamps_.end() &&
        judge(newest->second, toNs(transform.header.stamp)) == Verdict::kNew)
      real.push_back(transform);
  }
  left_out_.clear();
  return real;
}

void TfFeed::rebuildWithout(const std::string& child) {
  statics_.erase(child);
  // tf2 cannot forget one frame's static parent: start a new buffer with the statics kept. The
  // dynamic history is lost then, once for each such frame, when it is first seen moving (normally at
  // start-up).
  auto rebuilt = std::make_unique<tf2::BufferCore>(cache_time_);
  for (const auto& [frame, history] : statics_)
    rebuilt->setTransform(history.back().transform, "tf_static", true);
  buffer_ = std::move(rebuilt);
  motion_.setBuffer(*buffer_);
  motion_.clearSamples();
  newest_link_stamps_.clear();
  newest_dynamic_stamps_.clear();
  backward_.clear();
  held_.clear();
  planChain();
}

void TfFeed::setParent(const std::string& child, const std::string& parent) {
  std::string& known = parents_[child];
  if (known == parent)
    return;  // the tree is as it was: so is the chain (not walked again for every transform)
  known = parent;
  chainChanged();
}

void TfFeed::chainChanged() {
  chain_ = chainChildren();
  planChain();
}

void TfFeed::planChain() {
  // tf2's walk from the base up to the fixed frame, through the parents as last seen: one dynamic link
  // and statics around it; the fixed frame's own link, if any, read as tf2 reads it.
  OneLinkChain& chain = motion_.chain();
  std::vector<OneLinkChain::Link> below, above;
  const std::string* moving = nullptr;
  const std::string* moving_parent = nullptr;
  std::string frame = base_frame_;
  for (std::size_t steps = 0; frame != fixed_frame_; ++steps) {
    const auto parent = parents_.find(frame);
    if (parent == parents_.end() || steps > parents_.size()) {
      chain.clearChain();  // not connected (or a loop)
      return;
    }
    if (moving_.count(frame) > 0) {
      if (moving) {
        chain.clearChain();  // a second dynamic link
        return;
      }
      moving = &parent->first;
      moving_parent = &parent->second;
    } else {
      const auto kept = statics_.find(frame);
      if (kept == statics_.end()) {
        chain.clearChain();
        return;
      }
      const geometry_msgs::Transform& link = kept->second.back().transform.transform;  // tf2's
      (moving ? above : below)
          .push_back({tf2::Quaternion(link.rotation.x, link.rotation.y, link.rotation.z, link.rotation.w),
                      tf2::Vector3(link.translation.x, link.translation.y, link.translation.z)});
    }
    frame = parent->second;
  }
  if (!moving) {
    chain.clearChain();
    return;
  }
  const OneLinkChain::FixedLink fixed_link =
      moving_.count(fixed_frame_) > 0    ? OneLinkChain::FixedLink::kDynamic
      : statics_.count(fixed_frame_) > 0 ? OneLinkChain::FixedLink::kStatic
                                         : OneLinkChain::FixedLink::kNone;
  const auto newest = newest_dynamic_stamps_.find(*moving);
  chain.setChain(*moving, *moving_parent, std::move(below), std::move(above), fixed_link,
                 newest == newest_dynamic_stamps_.end() ? 0 : newest->second);
}

std::set<std::string> TfFeed::chainChildren() const {
  // From the base up through the parents seen, to the fixed frame; the children on the way that move.
  std::set<std::string> children;
  std::string frame = base_frame_;
  for (std::size_t steps = 0; frame != fixed_frame_ && steps < parents_.size(); ++steps) {
    const auto parent = parents_.find(frame);
    if (parent == parents_.end())
      break;
    if (moving_.count(frame))
      children.insert(frame);
    frame = parent->second;
  }
  return children;
}

Coverage TfFeed::coverage(core::TimeNs first, core::TimeNs last, std::string* why) const {
  const auto never = [why](const std::string& text) {
    if (why)
      *why = text;
    return Coverage::kNever;
  };
  const core::TimeNs newest = newestChainTime();
  if (newest != 0 && (first + kFarNs < newest || last > newest + kFarNs)) {
    const bool before = first < newest;
    return never("the sweep lies " +
                 formatNumber(core::nsToSeconds(before ? newest - first : last - newest)) + " s " +
                 (before ? "before" : "after") + " tf's newest " + fixed_frame_ + " -> " + base_frame_ +
                 " (" + std::to_string(core::nsToSeconds(newest)) +
                 "): a stamp tf cannot cover (uninitialised, or on another clock)");
  }
  // One dynamic link: its samples kept answer without tf2 where they hold the times.
  const OneLinkChain& chain = motion_.chain();
  if (chain.answers(last) && chain.answers(first))
    return Coverage::kCovered;
  try {
    std::string error;
    return buffer_->canTransform(fixed_frame_, base_frame_, toRosTime(last), &error) &&
                   buffer_->canTransform(fixed_frame_, base_frame_, toRosTime(first), &error)
               ? Coverage::kCovered
               : Coverage::kNotYet;
  } catch (const std::exception& error) {  // ros::Time's "out of dual 32-bit range" inside tf2
    return never("tf2 cannot take the sweep's times (" + std::to_string(core::nsToSeconds(first)) + " to " +
                 std::to_string(core::nsToSeconds(last)) + "): " + error.what());
  }
}

std::vector<std::string> TfFeed::sortedFrames() const {
  std::vector<std::string> frames;
  buffer_->_getFrameStrings(frames);
  std::sort(frames.begin(), frames.end());
  return frames;
}

std::string TfFeed::frameList() const {
  std::string known;
  for (const std::string& name : sortedFrames())
    known += (known.empty() ? "" : ", ") + name;
  return known.empty() ? "none" : known;
}

std::string TfFeed::unknownFrame(const std::string& frame, const std::string& what) const {
  const std::string closest = closestName(frame, sortedFrames());
  return what + " '" + frame + "' is unknown to tf" +
         (closest.empty() ? "" : " (did you mean '" + closest + "'?)") + "; tf's frames: " + frameList();
}

std::string TfFeed::unknownChainFrame() const {
  if (!buffer_->_frameExists(fixed_frame_))
    return unknownFrame(fixed_frame_, "fixed_frame");
  if (!buffer_->_frameExists(base_frame_))
    return unknownFrame(base_frame_, "base_frame");
  return "";
}

std::string TfFeed::whyNotCovered(core::TimeNs first, core::TimeNs last, core::TimeNs arrival) const {
  const std::string chain = "tf " + fixed_frame_ + " -> " + base_frame_;
  if (std::string unknown = unknownChainFrame(); !unknown.empty())
    return unknown;
  const core::TimeNs cache = cache_time_.toNSec();
  for (const auto& [child, parents] : dynamic_parents_) {
    for (auto a = parents.begin(); a != parents.end(); ++a) {
      for (auto b = std::next(a); b != parents.end(); ++b) {
        if (std::abs(a->second - b->second) <= cache) {
          return chain + ": " + child + " has two parents on /tf, " + a->first + " and " + b->first +
                 " (two publishers of " + child + "?)";
        }
      }
    }
  }
  std::string error;
  const core::TimeNs newest = newestChainTime();
  if (newest == 0) {
    try {
      buffer_->canTransform(fixed_frame_, base_frame_, ros::Time(0), &error);
    } catch (const std::exception& thrown) {
      error = thrown.what();
    }
    return chain + ": the frames are not connected: " + error;
  }
  const auto ms = [](core::TimeNs ns) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f ms", 1e3 * core::nsToSeconds(ns));
    return std::string(text);
  };
  if (newest < last) {
    // A sweep ending after its arrival (on the stamps' clock) by up to time_offset's range: stamped late.
    // Further off, the owner's clock is another than the stamps'.
    if (last > arrival + 1'000'000 && last < arrival + kLateStampNs) {
      return chain + " ends " + ms(last - newest) + " before the sweep's end, which lies " +
             ms(last - arrival) + " after the " +
             "arrival: a driver stamping late (at the sweep's end, or with a delay)? Set time_offset " +
             "(deskew_calibrate finds it from a recording), or give tf longer with a longer tf_timeout";
    }
    return chain + " has not reached the sweep's end: its newest is " + ms(last - newest) + " before it";
  }
  try {
    buffer_->canTransform(fixed_frame_, base_frame_, toRosTime(first), &error);
  } catch (const std::exception& thrown) {
    error = thrown.what();
  }
  return chain + " has nothing at the sweep's start, " + ms(newest - first) +
         " before its newest (tf keeps " + formatNumber(cacheTime()) + " s): " + error;
}

std::string TfFeed::whyNoMount(const std::string& frame) const {
  if (!buffer_->_frameExists(base_frame_))
    return unknownFrame(base_frame_, "base_frame");
  if (!buffer_->_frameExists(frame))
    return unknownFrame(frame, "the scan's frame");
  std::string error;
  try {
    buffer_->canTransform(base_frame_, frame, ros::Time(0), &error);
  } catch (const std::exception& thrown) {
    error = thrown.what();
  }
  return "not connected to " + base_frame_ + ": " + error;
}

std::string TfFeed::whyNoChain() const {
  std::string error;
  try {
    if (buffer_->canTransform(fixed_frame_, base_frame_, ros::Time(0), &error))
      return "";
  } catch (const std::exception& thrown) {
    error = thrown.what();
  }
  if (std::string unknown = unknownChainFrame(); !unknown.empty())
    return unknown;
  return "tf " + fixed_frame_ + " -> " + base_frame_ + ": the frames are not connected (" + error +
         "); tf's frames: " + frameList();
}

core::TimeNs TfFeed::newestChainTime() const {
  if (const core::TimeNs newest = motion_.chain().newest(); newest != 0)
    return newest;  // one dynamic link: its newest sample, as tf2's walk from the base finds it
  if (!buffer_->_frameExists(fixed_frame_) || !buffer_->_frameExists(base_frame_))
    return 0;  // what tf2's lookup would throw for, without the cost of a throw
  try {
    return toNs(buffer_->lookupTransform(fixed_frame_, base_frame_, ros::Time(0)).header.stamp);
  } catch (const std::exception&) {  // tf2's, or ros::Time's
    return 0;
  }
}

bool TfFeed::mountKnown(const std::string& frame) const {
  std::string error;
  try {
    return mounts_.count(frame) > 0 || buffer_->canTransform(base_frame_, frame, ros::Time(0), &error);
  } catch (const std::exception&) {
    return false;
  }
}

void TfFeed::recordStatic(const geometry_msgs::TransformStamped& transform) {
  std::vector<StaticLink>& history = statics_[transform.child_frame_id];
  const core::TimeNs stamp = toNs(transform.header.stamp);
  // The newest publication holds from its stamp on: those stamped at or after it are superseded (a
  // static re-sent stamped 0 replaces them all; a bag played again re-sends its statics).
  history.erase(std::lower_bound(history.begin(), history.end(), stamp,
                                 [](const StaticLink& link, core::TimeNs t) { return link.stamp < t; }),
                history.end());
  StaticLink link;
  link.stamp = stamp;
  link.transform = transform;
  link.pose = toPose(transform.transform);
  if (!history.empty() && history.back().transform.header.frame_id == transform.header.frame_id &&
      samePose(history.back().pose, link.pose)) {
    history.back().transform = transform;  // the same link again: nothing changes (tf2 gets the newest)
    return;
  }
  // Publications whose time is over (a next one stamped more than the cache time before this one) can
  // serve no sweep still to come: a static re-published at a rate stays bounded.
  const core::TimeNs horizon = stamp - static_cast<core::TimeNs>(cache_time_.toNSec());
  const auto over = std::upper_bound(history.begin(), history.end(), horizon,
                                     [](core::TimeNs t, const StaticLink& l) { return t < l.stamp; });
  if (over != history.begin())
    history.erase(history.begin(), std::prev(over));
  history.push_back(std::move(link));
}

TfFeed::Link TfFeed::linkAt(const std::string& child, core::TimeNs time, const std::string*& parent,
                            mrpt::poses::CPose3D& pose) const {
  if (moving_.count(child) > 0) {
    const auto known = parents_.find(child);
    if (known == parents_.end())
      return Link::kFailed;
    parent = &known->second;
    // At the sweep's end; tf's newest when it has not reached it (a mount on /tf is not waited for).
    // Asked first, so that the usual miss throws nothing.
    try {
      ros::Time at = toRosTime(time);
      if (!buffer_->canTransform(*parent, child, at))
        at = ros::Time(0);
      pose = toPose(buffer_->lookupTransform(*parent, child, at).transform);
      return Link::kFound;
    } catch (const std::exception&) {  // tf2's, or ros::Time's
      return Link::kFailed;
    }
  }
  const auto kept = statics_.find(child);
  if (kept == statics_.end())
    return Link::kRoot;
  const std::vector<StaticLink>& history = kept->second;
  // The last publication stamped at or before `time`; the first when none is (a mount that arrived
  // late serves the sweeps that waited for it). Time 0: the newest.
  auto in_force = time == 0
                      ? history.end()
                      : std::upper_bound(history.begin(), history.end(), time,
                                         [](core::TimeNs t, const StaticLink& l) { return t < l.stamp; });
  if (in_force != history.begin())
    --in_force;
  parent = &in_force->transform.header.frame_id;
  pose = in_force->pose;
  return Link::kFound;
}

bool TfFeed::mountAt(const std::string& frame, core::TimeNs time, mrpt::poses::CPose3D& mount) const {
  // Up from the scan's frame (poses of it in each ancestor) until the base; failing that, up from the
  // base until a frame of the first walk: the two meet there. Fixed arrays: no allocation.
  constexpr std::size_t kDepth = 16;
  std::array<const std::string*, kDepth> frames{};
  std::array<mrpt::poses::CPose3D, kDepth> in;  // in[k]: the scan frame in frames[k]
  frames[0] = &frame;
  std::size_t count = 1;
  const std::string* parent = nullptr;
  mrpt::poses::CPose3D link;
  for (;;) {
    if (*frames[count - 1] == base_frame_) {
      mount = in[count - 1];
      return true;
    }
    if (count == kDepth)
      return false;
    const Link found = linkAt(*frames[count - 1], time, parent, link);
    if (found == Link::kFailed)
      return false;
    if (found == Link::kRoot)
      break;
    frames[count] = parent;
    in[count] = link + in[count - 1];
    ++count;
  }
  const std::string* ancestor = &base_frame_;
  mrpt::poses::CPose3D base;  // the base in `ancestor`
  for (std::size_t step = 0; step < kDepth; ++step) {
    for (std::size_t k = 0; k < count; ++k) {
      if (*frames[k] == *ancestor) {
        mount = in[k] - base;
        return true;
      }
    }
    if (linkAt(*ancestor, time, parent, link) != Link::kFound)
      return false;
    ancestor = parent;
    base = link + base;
  }
  return false;
}

std::optional<mrpt::poses::CPose3D> TfFeed::mount(const std::string& frame, core::TimeNs time,
                                                  std::string& error) {
  // Looked up for every sweep: a re-published /tf_static (recalibration) serves the sweeps that end at
  // or after its stamp, however late it arrives; a mount on /tf is taken at the sweep's end. One value
  // serves the whole sweep.
  const auto known = mounts_.find(frame);
  mrpt::poses::CPose3D mount;
  if (!mountAt(frame, time, mount)) {
    // The histories do not connect the frames at `time` (a static re-parented since): tf2's newest.
    try {
      mount = toPose(buffer_->lookupTransform(base_frame_, frame, ros::Time(0)).transform);
    } catch (const std::exception& lookup_error) {  // tf2's, or ros::Time's
      if (known != mounts_.end())  // the tf cache was cleared (time jump): keep the last mount
        return known->second;
      error = lookup_error.what();
      return std::nullopt;
    }
  }
  if (known != mounts_.end() && samePose(known->second, mount))
    return mount;
  const std::string text = base_frame_ + " -> " + frame + ": " + describePose(mount);
  notify(known == mounts_.end() ? TfEvent::kMountFirst : TfEvent::kMountChanged, text);
  mounts_[frame] = mount;
  return mount;
}

}  // namespace lidar_deskew::ros_adapter
