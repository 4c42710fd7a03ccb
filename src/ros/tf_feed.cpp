#include "lidar_deskew/ros/tf_feed.h"

#include <tf2/exceptions.h>

#include <algorithm>
#include <cmath>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

/// A jump backwards of the chain's stamps larger than this (bag loop, /clock reset) clears the cache.
constexpr core::TimeNs kTimeJumpNs = 1'000'000'000;

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
    if (!buffer_->setTransform(transform, "tf_static", true)) {
      notify(TfEvent::kBadTransform, "tf2 refused /tf_static " + parent + " -> " + child);
      return true;
    }
    statics_[child] = transform;
    setParent(child, parent);
    return true;
  }

  bool in_time = true;
  if (moving_.insert(child).second) {
    chain_ = chainChildren();
    const auto kept = statics_.find(child);
    if (kept != statics_.end()) {
      ignored_statics_.insert(child);
      notify(TfEvent::kStaticIgnored, "ignoring /tf_static " + kept->second.header.frame_id + " -> " + child +
                                          " (" + describePose(toPose(kept->second.transform)) +
                                          "): " + child + " moves on /tf (from " + parent + ", " +
                                          describePose(toPose(transform.transform)) + ")");
      rebuildWithout(child);
    }
  }
  setParent(child, parent);
  const bool on_chain = chain_.count(child) > 0;
  const core::TimeNs stamp = toNs(transform.header.stamp);
  if (on_chain) {
    // Each link against its own newest stamp: links of one chain may lag or lead each other by more
    // than a second (a localiser future-dating map -> odom), and that is no jump.
    core::TimeNs& newest = newest_link_stamps_[child];
    if (newest != 0 && stamp + kTimeJumpNs < newest) {
      notify(TfEvent::kTimeJump, "time went backwards (" + parent + " -> " + child + ", " +
                                     std::to_string(core::nsToSeconds(newest - stamp)) +
                                     " s): clearing the tf cache");
      forgetMotion();
      in_time = false;
    }
    newest_link_stamps_[child] = std::max(newest_link_stamps_[child], stamp);
  }
  if (!buffer_->setTransform(transform, "tf", false)) {
    notify(TfEvent::kBadTransform, "tf2 refused /tf " + parent + " -> " + child);
    return in_time;
  }
  if (on_chain) {
    motion_.addSampleTime(stamp);
    // One dynamic link straight from fixed to base: its stamps are all of the chain's samples.
    motion_.setSingleLink(chain_.size() == 1 && parent == fixed_frame_ && child == base_frame_);
  }
  return in_time;
}

void TfFeed::forgetMotion() {
  buffer_->clear();
  motion_.clearSampleTimes();
  newest_link_stamps_.clear();
}

void TfFeed::rebuildWithout(const std::string& child) {
  statics_.erase(child);
  // tf2 cannot forget one frame's static parent: start a new buffer with the statics kept. The
  // dynamic history is lost then, once for each such frame, when it is first seen moving (normally at
  // start-up).
  auto rebuilt = std::make_unique<tf2::BufferCore>(cache_time_);
  for (const auto& [frame, transform] : statics_)
    rebuilt->setTransform(transform, "tf_static", true);
  buffer_ = std::move(rebuilt);
  motion_.setBuffer(*buffer_);
  motion_.clearSampleTimes();
  newest_link_stamps_.clear();
}

void TfFeed::setParent(const std::string& child, const std::string& parent) {
  std::string& known = parents_[child];
  if (known == parent)
    return;  // the tree is as it was: so is the chain (not walked again for every transform)
  known = parent;
  chain_ = chainChildren();
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

bool TfFeed::covers(core::TimeNs first, core::TimeNs last) const {
  std::string error;
  return buffer_->canTransform(fixed_frame_, base_frame_, toRosTime(last), &error) &&
         buffer_->canTransform(fixed_frame_, base_frame_, toRosTime(first), &error);
}

core::TimeNs TfFeed::newestChainTime() const {
  try {
    return toNs(buffer_->lookupTransform(fixed_frame_, base_frame_, ros::Time(0)).header.stamp);
  } catch (const tf2::TransformException&) {
    return 0;
  }
}

bool TfFeed::mountKnown(const std::string& frame) const {
  std::string error;
  return mounts_.count(frame) > 0 || buffer_->canTransform(base_frame_, frame, ros::Time(0), &error);
}

std::optional<mrpt::poses::CPose3D> TfFeed::mount(const std::string& frame, std::string& error) {
  // Looked up for every scan (about a microsecond): a re-published /tf_static (recalibration) or a
  // mount on /tf is followed from the next scan on. The newest value serves the whole sweep.
  const auto known = mounts_.find(frame);
  mrpt::poses::CPose3D mount;
  try {
    mount = toPose(buffer_->lookupTransform(base_frame_, frame, ros::Time(0)).transform);
  } catch (const tf2::TransformException& lookup_error) {
    if (known != mounts_.end())  // the tf cache was cleared (time jump): keep the last mount
      return known->second;
    error = lookup_error.what();
    return std::nullopt;
  }
  if (known != mounts_.end() && samePose(known->second, mount))
    return mount;
  const std::string text = base_frame_ + " -> " + frame + ": " + describePose(mount);
  notify(known == mounts_.end() ? TfEvent::kMountFirst : TfEvent::kMountChanged, text);
  mounts_[frame] = mount;
  return mount;
}

}  // namespace lidar_deskew::ros_adapter
