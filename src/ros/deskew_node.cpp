#include "lidar_deskew/ros/deskew_node.h"

#include <mrpt/math/CMatrixFixed.h>
#include <pcl_ros/point_cloud.h>
#include <tf2/exceptions.h>

#include <atomic>
#include <cstdio>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

std::atomic<const void*> last_published_cloud{nullptr};

/// A time jump backwards larger than this (bag loop, /clock reset) clears the tf cache and the queue.
const core::TimeNs kTimeJumpNs = 1'000'000'000;

/// [s] The timer that expires scans waiting for tf longer than tf_timeout.
constexpr double kTimerPeriod = 0.02;

/// Scans over which the latency percentile is taken.
constexpr std::size_t kLatencies = 1000;

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

/// Equal to 1e-9 in every entry of the homogeneous matrix: a re-published but unchanged mount.
bool samePose(const mrpt::poses::CPose3D& a, const mrpt::poses::CPose3D& b) {
  const auto difference = a.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen() -
                          b.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
  return difference.cwiseAbs().maxCoeff() <= 1e-9;
}

}  // namespace

LaserScanDeskewNode::LaserScanDeskewNode(ros::NodeHandle nh, ros::NodeHandle private_nh, std::string name)
    : nh_(nh),
      private_nh_(private_nh),
      name_(std::move(name)),
      params_(DeskewParams::load(private_nh)),
      buffer_(ros::Duration(10.0)),
      motion_(buffer_, params_.fixed_frame, params_.base_frame),
      processor_(params_) {
  last_diagnostics_ = last_tick_ = running_since_ = ros::WallTime::now();
  private_nh_.setParam("diagnostic_period", params_.diagnostics_period);  // read by the Updater
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh_, private_nh_, name_);
  diagnostics_->setHardwareID("none");
  diagnostics_->add(name_ + ": deskew", this, &LaserScanDeskewNode::produceDiagnostics);

  // Absolute names on the node's own handle: in a nodelet, tf then arrives on the nodelet's queue.
  tf_subscriber_ = nh_.subscribe<tf2_msgs::TFMessage>(
      "/tf", 100, [this](const tf2_msgs::TFMessage::ConstPtr& message) { tfCallback(message, false); },
      ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  tf_static_subscriber_ = nh_.subscribe<tf2_msgs::TFMessage>(
      "/tf_static", 100, [this](const tf2_msgs::TFMessage::ConstPtr& message) { tfCallback(message, true); },
      ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());

  {
    // Held while advertising: a subscriber connecting right away must see both publishers set.
    std::lock_guard<std::mutex> lock(connect_mutex_);
    const ros::SubscriberStatusCallback connect = [this](const ros::SingleSubscriberPublisher&) {
      connectCallback();
    };
    scan_publisher_ = nh_.advertise<sensor_msgs::LaserScan>("scan_deskewed", 10, connect, connect);
    cloud_publisher_ = nh_.advertise<DeskewedCloud>("scan_deskewed_points", 10, connect, connect);
  }
  timer_ = nh_.createWallTimer(ros::WallDuration(kTimerPeriod), &LaserScanDeskewNode::timerCallback, this);
  const std::string mode = params_.exact
                               ? "exact per-beam lookups"
                               : "knots every " + std::to_string(params_.deskew.knot_interval) + " s";
  ROS_INFO("%s: fixed_frame %s, base_frame %s, reference %s, %s, tf_timeout %.3f s, on_tf_failure %s",
           name_.c_str(), params_.fixed_frame.c_str(), params_.base_frame.c_str(),
           core::toString(params_.deskew.reference).c_str(), mode.c_str(), params_.tf_timeout,
           toString(params_.on_tf_failure).c_str());
}

LaserScanDeskewNode::~LaserScanDeskewNode() {
  {
    // No connect callback may touch a publisher or subscribe while members go away.
    std::lock_guard<std::mutex> lock(connect_mutex_);
    shutting_down_ = true;
    scan_publisher_.shutdown();
    cloud_publisher_.shutdown();
  }
  timer_.stop();
  scan_subscriber_.shutdown();
  tf_subscriber_.shutdown();
  tf_static_subscriber_.shutdown();
}

const void* LaserScanDeskewNode::lastPublishedCloud() {
  return last_published_cloud.load();
}

double LaserScanDeskewNode::latencyP99() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latencyP99Locked();
}

double LaserScanDeskewNode::latencyP99Locked() const {
  if (latencies_.empty())
    return 0.0;
  std::vector<double> sorted = latencies_;
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.99 * sorted.size())) - 1;
  std::nth_element(sorted.begin(), sorted.begin() + rank, sorted.end());
  return sorted[rank];
}

LaserScanDeskewNode::Counters LaserScanDeskewNode::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

void LaserScanDeskewNode::connectCallback() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  if (shutting_down_)
    return;
  const bool wanted = scan_publisher_.getNumSubscribers() + cloud_publisher_.getNumSubscribers() > 0;
  if (wanted && !scan_subscriber_) {
    scan_subscriber_ = nh_.subscribe<sensor_msgs::LaserScan>("scan", 10, &LaserScanDeskewNode::scanCallback,
                                                             this, ros::TransportHints().tcpNoDelay());
  } else if (!wanted && scan_subscriber_) {
    scan_subscriber_.shutdown();
  }
}

void LaserScanDeskewNode::scanCallback(const sensor_msgs::LaserScan::ConstPtr& message) {
  const ros::WallTime arrival = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  ++counters_.received;
  Pending pending;
  pending.arrival = arrival;
  try {
    pending.prepared = processor_.prepare(message);
  } catch (const core::InvalidInput& error) {
    ++counters_.dropped_invalid;
    ROS_ERROR_THROTTLE(1.0, "%s: dropping malformed scan (frame '%s', stamp %.6f): %s", name_.c_str(),
                       message->header.frame_id.c_str(), message->header.stamp.toSec(), error.what());
    return;
  } catch (const std::exception& error) {  // e.g. out of memory for an absurd scan
    ++counters_.dropped_invalid;
    ROS_ERROR_THROTTLE(1.0, "%s: dropping scan: %s", name_.c_str(), error.what());
    return;
  }
  if (pending.prepared.timing.source != core::TimingSource::kTimeIncrement &&
      counters_.time_fallbacks++ == 0) {
    ROS_WARN("%s: scans have time_increment = 0; beam times come from %s (counted in diagnostics)",
             name_.c_str(),
             pending.prepared.timing.source == core::TimingSource::kScanTime ? "scan_time"
                                                                             : "the scan_period parameter");
  }
  pending_.push_back(std::move(pending));
  while (static_cast<int>(pending_.size()) > params_.queue_size) {
    ++counters_.dropped_queue;
    ROS_WARN_THROTTLE(1.0, "%s: more than %d scans wait for tf; dropping the oldest", name_.c_str(),
                      params_.queue_size);
    pending_.pop_front();
  }
  try {
    processReady(arrival);
  } catch (const std::exception& error) {  // never let an exception reach the manager
    ROS_ERROR_THROTTLE(1.0, "%s: error processing scans: %s", name_.c_str(), error.what());
  }
}

void LaserScanDeskewNode::tfCallback(const tf2_msgs::TFMessage::ConstPtr& message, bool is_static) {
  const ros::WallTime arrival = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  try {
    for (const geometry_msgs::TransformStamped& transform : message->transforms) {
      if (!is_static && transform.child_frame_id == params_.base_frame) {
        // Only the base's own motion decides that time went backwards (other publishers may lag).
        const core::TimeNs stamp = toNs(transform.header.stamp);
        if (newest_base_stamp_ != 0 && stamp + kTimeJumpNs < newest_base_stamp_)
          resetForTimeJump();
        newest_base_stamp_ = std::max(newest_base_stamp_, stamp);
      }
      if (!is_static)
        motion_.observe(transform);
      if (is_static && transform.child_frame_id == params_.base_frame) {
        // The base moves: a static parent for it would make tf answer one pose for all times.
        ROS_WARN_ONCE("%s: ignoring /tf_static %s -> %s: %s moves", name_.c_str(),
                      transform.header.frame_id.c_str(), transform.child_frame_id.c_str(),
                      params_.base_frame.c_str());
        continue;
      }
      try {
        buffer_.setTransform(transform, "tf", is_static);
      } catch (const tf2::TransformException& error) {
        ROS_WARN_THROTTLE(1.0, "%s: ignoring a transform: %s", name_.c_str(), error.what());
      }
    }
    processReady(arrival);
  } catch (const std::exception& error) {  // never let an exception reach the manager
    ROS_ERROR_THROTTLE(1.0, "%s: error handling tf: %s", name_.c_str(), error.what());
  }
}

void LaserScanDeskewNode::timerCallback(const ros::WallTimerEvent& /*event*/) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::WallTime now = ros::WallTime::now();
    // After a stall of this process (descheduled, swapped out, stopped), tf that came meanwhile may
    // not have been read yet: expire nothing until it has run for two timer periods again, so that
    // our own stall is never taken for tf being late.
    if ((now - last_tick_).toSec() > 2 * kTimerPeriod)
      running_since_ = now;
    last_tick_ = now;
    const bool settled = (now - running_since_).toSec() >= 2 * kTimerPeriod;
    try {
      processReady(now);
      while (settled && !pending_.empty() && (now - pending_.front().arrival).toSec() > params_.tf_timeout) {
        const Pending expired = std::move(pending_.front());
        pending_.pop_front();
        const std::string& frame = expired.prepared.message->header.frame_id;
        if (!mountKnown(frame)) {
          ++counters_.dropped_mount;
          ROS_ERROR_THROTTLE(1.0,
                             "%s: dropping scan: no transform %s -> %s (the laser mount) within tf_timeout",
                             name_.c_str(), params_.base_frame.c_str(), frame.c_str());
        } else {
          failOnTf(expired, "tf did not cover the sweep within tf_timeout");
        }
        processReady(now);  // scans behind an expired one may be ready: serve them before they expire
      }
    } catch (const std::exception& error) {  // never let an exception reach the manager
      ROS_ERROR_THROTTLE(1.0, "%s: error processing scans: %s", name_.c_str(), error.what());
    }
  }
  diagnostics_->update();
}

void LaserScanDeskewNode::resetForTimeJump() {
  ++counters_.time_jumps;
  ROS_WARN("%s: time went backwards (%s -> %s motion): clearing the tf cache and %zu waiting scans",
           name_.c_str(), params_.fixed_frame.c_str(), params_.base_frame.c_str(), pending_.size());
  buffer_.clear();
  motion_.clearSampleTimes();
  pending_.clear();
  newest_base_stamp_ = 0;
}

bool LaserScanDeskewNode::sweepCovered(const Pending& pending, bool& extrapolate) const {
  extrapolate = false;
  const ros::Time first = toRosTime(pending.prepared.timing.earliestBeamTime());
  const ros::Time last = toRosTime(pending.prepared.timing.latestBeamTime());
  if (buffer_.canTransform(params_.fixed_frame, params_.base_frame, last) &&
      buffer_.canTransform(params_.fixed_frame, params_.base_frame, first)) {
    return true;
  }
  if (params_.max_extrapolation <= 0.0 ||
      !buffer_.canTransform(params_.fixed_frame, params_.base_frame, first))
    return false;
  // tf of the chain ends inside the sweep, less than max_extrapolation before its last beam.
  const core::TimeNs newest = newestChainTime();
  extrapolate = newest >= toNs(first) && newest + core::secondsToNs(params_.max_extrapolation) >= toNs(last);
  return extrapolate;
}

core::TimeNs LaserScanDeskewNode::newestChainTime() const {
  try {
    return toNs(buffer_.lookupTransform(params_.fixed_frame, params_.base_frame, ros::Time(0)).header.stamp);
  } catch (const tf2::TransformException&) {
    return 0;
  }
}

void LaserScanDeskewNode::processReady(ros::WallTime trigger) {
  while (!pending_.empty()) {
    bool extrapolate = false;
    // The mount may arrive after the motion (other connection): wait for both. tf only grows, so
    // later scans wait too.
    if (!mountKnown(pending_.front().prepared.message->header.frame_id) ||
        !sweepCovered(pending_.front(), extrapolate))
      return;
    const Pending ready = std::move(pending_.front());
    pending_.pop_front();
    correctAndPublish(ready, extrapolate, trigger);
  }
}

bool LaserScanDeskewNode::mountKnown(const std::string& frame) const {
  return mounts_.count(frame) > 0 || buffer_.canTransform(params_.base_frame, frame, ros::Time(0));
}

bool LaserScanDeskewNode::lookupMount(const std::string& frame, mrpt::poses::CPose3D& mount) {
  // Looked up for every scan (about a microsecond): a re-published /tf_static (recalibration) or a
  // mount on /tf is followed from the next scan on. The newest value serves the whole sweep.
  const auto known = mounts_.find(frame);
  try {
    mount = toPose(buffer_.lookupTransform(params_.base_frame, frame, ros::Time(0)).transform);
  } catch (const tf2::TransformException& error) {
    if (known != mounts_.end()) {  // the tf cache was cleared (time jump): keep the last mount
      mount = known->second;
      return true;
    }
    ROS_ERROR_THROTTLE(1.0, "%s: no transform %s -> %s for the laser mount: %s", name_.c_str(),
                       params_.base_frame.c_str(), frame.c_str(), error.what());
    return false;
  }
  if (known != mounts_.end() && samePose(known->second, mount))
    return true;
  char text[160];
  std::snprintf(text, sizeof text, "%s -> %s: x %.3f y %.3f z %.3f m, yaw %.4f pitch %.4f roll %.4f rad",
                params_.base_frame.c_str(), frame.c_str(), mount.x(), mount.y(), mount.z(), mount.yaw(),
                mount.pitch(), mount.roll());
  if (known == mounts_.end()) {
    ROS_INFO("%s: mount %s", name_.c_str(), text);
  } else {
    ++counters_.mount_changes;  // a mount moving on /tf changes often: log at most every 5 s
    ROS_INFO_THROTTLE(5.0, "%s: mount changed (counted in diagnostics): %s", name_.c_str(), text);
  }
  mounts_[frame] = mount;
  return true;
}

void LaserScanDeskewNode::correctAndPublish(const Pending& pending, bool extrapolate, ros::WallTime trigger) {
  const ros::WallTime start = ros::WallTime::now();
  const double tf_wait = std::max(0.0, (trigger - pending.arrival).toSec());
  mrpt::poses::CPose3D mount;
  if (!lookupMount(pending.prepared.message->header.frame_id, mount)) {
    ++counters_.dropped_mount;
    return;
  }
  DeskewedOutputs outputs;
  try {
    if (extrapolate) {
      std::vector<core::TimeNs> samples;
      const core::TimeNs newest = newestChainTime();
      motion_.appendSampleTimes(newest - 1'000'000'000, newest, samples);
      const core::TimeNs previous = samples.empty() ? newest : samples.back();
      const ExtrapolatingMotion motion(motion_, newest, previous,
                                       newest + core::secondsToNs(params_.max_extrapolation));
      outputs = processor_.correct(pending.prepared, mount, motion);
      ++counters_.extrapolated;
    } else {
      outputs = processor_.correct(pending.prepared, mount, motion_);
    }
  } catch (const TfGapTooLong& error) {
    ++counters_.tf_gaps;
    failOnTf(pending, error.what());
    return;
  } catch (const core::MotionUnavailable& error) {
    failOnTf(pending, error.what());
    return;
  }
  // Shared pointers, never touched after publishing: same-type subscribers in the manager get them as is.
  scan_publisher_.publish(outputs.scan);
  last_published_cloud.store(outputs.cloud.get());
  cloud_publisher_.publish(outputs.cloud);

  ++counters_.published;
  const ros::WallTime done = ros::WallTime::now();
  const double processing = (done - start).toSec();
  if (latencies_.size() < kLatencies) {
    latencies_.push_back((done - trigger).toSec());
  } else {
    latencies_[next_latency_] = (done - trigger).toSec();
    next_latency_ = (next_latency_ + 1) % kLatencies;
  }
  counters_.tf_wait_total += tf_wait;
  counters_.tf_wait_max = std::max(counters_.tf_wait_max, tf_wait);
  counters_.processing_total += processing;
  counters_.processing_max = std::max(counters_.processing_max, processing);
}

void LaserScanDeskewNode::failOnTf(const Pending& pending, const std::string& reason) {
  const double stamp = pending.prepared.message->header.stamp.toSec();
  if (params_.on_tf_failure == OnTfFailure::kDrop) {
    ++counters_.dropped_tf;
    ROS_WARN_THROTTLE(1.0, "%s: dropping scan at %.6f: %s", name_.c_str(), stamp, reason.c_str());
    return;
  }
  ++counters_.passed_through;
  ROS_WARN_THROTTLE(1.0, "%s: passing scan at %.6f through uncorrected: %s", name_.c_str(), stamp,
                    reason.c_str());
  const DeskewedOutputs outputs = processor_.passThrough(pending.prepared);
  scan_publisher_.publish(outputs.scan);
  cloud_publisher_.publish(outputs.cloud);
}

void LaserScanDeskewNode::produceDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::WallTime now = ros::WallTime::now();
  const double elapsed = std::max(1e-9, (now - last_diagnostics_).toSec());
  const Counters& was = counters_at_last_diagnostics_;
  const std::uint64_t dropped =
      counters_.dropped_invalid + counters_.dropped_tf + counters_.dropped_mount + counters_.dropped_queue;
  const std::uint64_t dropped_before =
      was.dropped_invalid + was.dropped_tf + was.dropped_mount + was.dropped_queue;
  if (dropped > dropped_before) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropping scans");
  } else if (counters_.passed_through > was.passed_through) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "passing scans through uncorrected");
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "ok");
  }
  status.add("input rate [Hz]", (counters_.received - was.received) / elapsed);
  status.add("output rate [Hz]", (counters_.published - was.published) / elapsed);
  status.add("received", counters_.received);
  status.add("published", counters_.published);
  status.add("passed through", counters_.passed_through);
  status.add("extrapolated", counters_.extrapolated);
  status.add("dropped: invalid", counters_.dropped_invalid);
  status.add("dropped: tf", counters_.dropped_tf);
  status.add("dropped: mount", counters_.dropped_mount);
  status.add("dropped: queue", counters_.dropped_queue);
  status.add("time_increment fallbacks", counters_.time_fallbacks);
  status.add("tf gaps", counters_.tf_gaps);
  status.add("mount changes", counters_.mount_changes);
  status.add("time jumps", counters_.time_jumps);
  status.add("waiting scans", pending_.size());
  const double done = std::max<std::uint64_t>(1, counters_.published);
  status.add("tf wait mean [ms]", 1e3 * counters_.tf_wait_total / done);
  status.add("tf wait max [ms]", 1e3 * counters_.tf_wait_max);
  status.add("processing mean [us]", 1e6 * counters_.processing_total / done);
  status.add("processing max [us]", 1e6 * counters_.processing_max);
  status.add("latency p99 [ms]", 1e3 * latencyP99Locked());
  counters_at_last_diagnostics_ = counters_;
  last_diagnostics_ = now;
}

}  // namespace lidar_deskew::ros_adapter
