#include "lidar_deskew/ros/deskew_node.h"

#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <tf2/exceptions.h>

#include <atomic>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

std::atomic<const void*> last_published_cloud{nullptr};

/// A time jump backwards larger than this (bag loop, /clock reset) clears the tf cache and the queue.
const ros::Duration kTimeJump(1.0);

/// Scans over which the latency percentile is taken.
constexpr std::size_t kLatencies = 1000;

/// The base stands still: correcting with it is the plain polar projection (pass_through clouds).
class StandingStill final : public core::MotionSource {
 public:
  mrpt::poses::CPose3D basePose(core::TimeNs /*time*/) const override { return {}; }
};

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

 private:
  const TfMotionSource& tf_;
  core::TimeNs newest_, previous_, limit_;
};

/// The corrected points as the published PCL cloud.
boost::shared_ptr<DeskewedCloud> toCloud(const core::DeskewedScan& corrected,
                                         const std_msgs::Header& header) {
  auto cloud = boost::make_shared<DeskewedCloud>();
  pcl_conversions::toPCL(header, cloud->header);
  cloud->points.reserve(corrected.points.size());
  for (const core::DeskewedPoint& point : corrected.points) {
    PointXYZITI out;
    out.x = static_cast<float>(point.position.x());
    out.y = static_cast<float>(point.position.y());
    out.z = static_cast<float>(point.position.z());
    out.intensity = point.intensity;
    out.t = static_cast<float>(point.time_offset);
    out.index = point.beam_index;
    cloud->points.push_back(out);
  }
  cloud->width = static_cast<std::uint32_t>(cloud->points.size());
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

}  // namespace

LaserScanDeskewNode::LaserScanDeskewNode(ros::NodeHandle nh, ros::NodeHandle private_nh, std::string name)
    : nh_(nh),
      private_nh_(private_nh),
      name_(std::move(name)),
      params_(DeskewParams::load(private_nh)),
      buffer_(ros::Duration(10.0)),
      motion_(buffer_, params_.fixed_frame, params_.base_frame),
      deskewer_(params_.deskew),
      rebinner_(params_.rebin) {
  last_diagnostics_ = ros::WallTime::now();
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
  timer_ = nh_.createWallTimer(ros::WallDuration(0.02), &LaserScanDeskewNode::timerCallback, this);
  const std::string mode = params_.exact
                               ? "exact per-beam lookups"
                               : "knots every " + std::to_string(params_.deskew.knot_interval) + " s";
  ROS_INFO("%s: fixed_frame %s, base_frame %s, reference %s, %s, tf_timeout %.3f s, on_tf_failure %s",
           name_.c_str(), params_.fixed_frame.c_str(), params_.base_frame.c_str(),
           core::toString(params_.deskew.reference).c_str(), mode.c_str(), params_.tf_timeout,
           toString(params_.on_tf_failure).c_str());
}

LaserScanDeskewNode::~LaserScanDeskewNode() {
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
  pending.message = message;
  pending.arrival = arrival;
  try {
    if (message->header.frame_id.empty())
      throw core::InvalidInput("header.frame_id", "is empty");
    pending.scan = fromMsg(*message);
    core::validateScan(pending.scan);
    pending.timing = core::resolveTiming(pending.scan, params_.timing);
  } catch (const core::InvalidInput& error) {
    ++counters_.dropped_invalid;
    ROS_ERROR_THROTTLE(1.0, "%s: dropping malformed scan (frame '%s', stamp %.6f): %s", name_.c_str(),
                       message->header.frame_id.c_str(), message->header.stamp.toSec(), error.what());
    return;
  }
  if (pending.timing.source != core::TimingSource::kTimeIncrement && counters_.time_fallbacks++ == 0) {
    ROS_WARN(
        "%s: scans have time_increment = 0; beam times come from %s (counted in diagnostics)", name_.c_str(),
        pending.timing.source == core::TimingSource::kScanTime ? "scan_time" : "the scan_period parameter");
  }
  if (!newest_scan_time_.isZero() && message->header.stamp + kTimeJump < newest_scan_time_) {
    resetForTimeJump("scan stamps");
  }
  newest_scan_time_ = message->header.stamp;
  pending_.push_back(std::move(pending));
  while (static_cast<int>(pending_.size()) > params_.queue_size) {
    ++counters_.dropped_queue;
    ROS_WARN_THROTTLE(1.0, "%s: more than %d scans wait for tf; dropping the oldest", name_.c_str(),
                      params_.queue_size);
    pending_.pop_front();
  }
  processReady(arrival);
}

void LaserScanDeskewNode::tfCallback(const tf2_msgs::TFMessage::ConstPtr& message, bool is_static) {
  const ros::WallTime arrival = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  for (const geometry_msgs::TransformStamped& transform : message->transforms) {
    if (!is_static) {
      if (!newest_tf_time_.isZero() && transform.header.stamp + kTimeJump < newest_tf_time_) {
        resetForTimeJump("tf stamps");
      }
      if (transform.header.stamp > newest_tf_time_)
        newest_tf_time_ = transform.header.stamp;
      if (transform.child_frame_id == params_.base_frame ||
          transform.header.frame_id == params_.fixed_frame) {
        motion_.addSampleTime(toNs(transform.header.stamp));
      }
    }
    try {
      buffer_.setTransform(transform, "tf", is_static);
    } catch (const tf2::TransformException& error) {
      ROS_WARN_THROTTLE(1.0, "%s: ignoring a transform: %s", name_.c_str(), error.what());
    }
  }
  processReady(arrival);
}

void LaserScanDeskewNode::timerCallback(const ros::WallTimerEvent& /*event*/) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::WallTime now = ros::WallTime::now();
    processReady(now);
    while (!pending_.empty() && (now - pending_.front().arrival).toSec() > params_.tf_timeout) {
      const Pending expired = std::move(pending_.front());
      pending_.pop_front();
      failOnTf(expired, "tf did not cover the sweep within tf_timeout");
    }
  }
  diagnostics_->update();
}

void LaserScanDeskewNode::resetForTimeJump(const std::string& what) {
  ++counters_.time_jumps;
  ROS_WARN("%s: time went backwards (%s): clearing the tf cache and %zu waiting scans", name_.c_str(),
           what.c_str(), pending_.size());
  buffer_.clear();
  motion_.clearSampleTimes();
  pending_.clear();
  newest_tf_time_ = ros::Time();
  newest_scan_time_ = ros::Time();
}

bool LaserScanDeskewNode::sweepCovered(const Pending& pending, bool& extrapolate) const {
  extrapolate = false;
  const ros::Time first = toRosTime(pending.timing.earliestBeamTime());
  const ros::Time last = toRosTime(pending.timing.latestBeamTime());
  if (buffer_.canTransform(params_.fixed_frame, params_.base_frame, last) &&
      buffer_.canTransform(params_.fixed_frame, params_.base_frame, first)) {
    return true;
  }
  if (params_.max_extrapolation <= 0.0 || newest_tf_time_.isZero())
    return false;
  // tf ends inside the sweep, less than max_extrapolation before its last beam.
  extrapolate = newest_tf_time_ >= first &&
                newest_tf_time_ + ros::Duration(params_.max_extrapolation) >= last &&
                buffer_.canTransform(params_.fixed_frame, params_.base_frame, first);
  return extrapolate;
}

void LaserScanDeskewNode::processReady(ros::WallTime trigger) {
  while (!pending_.empty()) {
    bool extrapolate = false;
    if (!sweepCovered(pending_.front(), extrapolate))
      return;  // tf only grows: later scans wait too
    const Pending ready = std::move(pending_.front());
    pending_.pop_front();
    correctAndPublish(ready, extrapolate, trigger);
  }
}

bool LaserScanDeskewNode::lookupMount(const std::string& frame, mrpt::poses::CPose3D& mount) {
  const auto cached = mounts_.find(frame);
  if (cached != mounts_.end()) {
    mount = cached->second;
    return true;
  }
  try {
    mount = toPose(buffer_.lookupTransform(params_.base_frame, frame, ros::Time(0)).transform);
  } catch (const tf2::TransformException& error) {
    ROS_ERROR_THROTTLE(1.0, "%s: no transform %s -> %s for the laser mount: %s", name_.c_str(),
                       params_.base_frame.c_str(), frame.c_str(), error.what());
    return false;
  }
  mounts_[frame] = mount;
  ROS_INFO("%s: mount %s -> %s: x %.3f y %.3f z %.3f m, yaw %.4f pitch %.4f roll %.4f rad", name_.c_str(),
           params_.base_frame.c_str(), frame.c_str(), mount.x(), mount.y(), mount.z(), mount.yaw(),
           mount.pitch(), mount.roll());
  return true;
}

void LaserScanDeskewNode::correctAndPublish(const Pending& pending, bool extrapolate, ros::WallTime trigger) {
  const ros::WallTime start = ros::WallTime::now();
  const double tf_wait = std::max(0.0, (trigger - pending.arrival).toSec());
  mrpt::poses::CPose3D mount;
  if (!lookupMount(pending.message->header.frame_id, mount)) {
    ++counters_.dropped_mount;
    return;
  }
  core::DeskewedScan corrected;
  try {
    if (extrapolate) {
      std::vector<core::TimeNs> samples;
      const core::TimeNs newest = toNs(newest_tf_time_);
      motion_.appendSampleTimes(newest - 1'000'000'000, newest, samples);
      const core::TimeNs previous = samples.empty() ? newest : samples.back();
      const ExtrapolatingMotion motion(motion_, newest, previous,
                                       newest + core::secondsToNs(params_.max_extrapolation));
      deskewer_.deskew(pending.scan, pending.timing, mount, motion, corrected);
      ++counters_.extrapolated;
    } else {
      deskewer_.deskew(pending.scan, pending.timing, mount, motion_, corrected);
    }
  } catch (const core::MotionUnavailable& error) {
    failOnTf(pending, error.what());
    return;
  }
  core::RebinnedScan rebinned;
  rebinner_.rebin(corrected,
                  {pending.scan.angle_min, pending.scan.angle_increment, pending.scan.ranges.size()},
                  core::noReturnValue(pending.scan), rebinned);

  const sensor_msgs::LaserScan& input = *pending.message;
  std_msgs::Header header = input.header;
  header.stamp = toRosTime(corrected.reference_time);

  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  scan->header = header;
  scan->angle_min = input.angle_min;
  scan->angle_max = input.angle_max;
  scan->angle_increment = input.angle_increment;
  scan->time_increment = 0.0f;  // every beam now refers to the reference time
  scan->scan_time = input.scan_time;
  scan->range_min = input.range_min;
  scan->range_max = input.range_max;
  scan->ranges = std::move(rebinned.ranges);
  scan->intensities = std::move(rebinned.intensities);
  const boost::shared_ptr<DeskewedCloud> cloud = toCloud(corrected, header);

  // Shared pointers, never touched after publishing: same-type subscribers in the manager get them as is.
  scan_publisher_.publish(scan);
  last_published_cloud.store(cloud.get());
  cloud_publisher_.publish(cloud);

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
  if (params_.on_tf_failure == OnTfFailure::kDrop) {
    ++counters_.dropped_tf;
    ROS_WARN_THROTTLE(1.0, "%s: dropping scan at %.6f: %s", name_.c_str(),
                      pending.message->header.stamp.toSec(), reason.c_str());
    return;
  }
  ++counters_.passed_through;
  ROS_WARN_THROTTLE(1.0, "%s: passing scan at %.6f through uncorrected: %s", name_.c_str(),
                    pending.message->header.stamp.toSec(), reason.c_str());
  scan_publisher_.publish(pending.message);
  // The uncorrected cloud: the plain polar projection, as if the base stood still.
  core::DeskewedScan projected;
  deskewer_.deskew(pending.scan, pending.timing, mrpt::poses::CPose3D(), StandingStill(), projected);
  cloud_publisher_.publish(toCloud(projected, pending.message->header));
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
