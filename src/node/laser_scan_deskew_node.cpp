#include "lidar_deskew/node/laser_scan_deskew_node.h"

#include <dynamic_reconfigure/server.h>
#include <pcl_ros/point_cloud.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <optional>
#include <type_traits>

#include "lidar_deskew/node/config_params.h"
#include "lidar_deskew/node/run_node.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::node {
namespace {

using ros_adapter::PipelineEvent;

std::atomic<const void*> last_published_cloud{nullptr};

/// [s] The timer that expires scans waiting for tf longer than tf_timeout.
constexpr double kTimerPeriod = 0.02;

/// Scans over which the latency percentile is taken.
constexpr std::size_t kLatencies = 1000;

/// How each pipeline event is logged: level, and the shortest interval between two lines [s].
struct LogPolicy {
  ros::console::levels::Level level;
  double period;
};

LogPolicy policyOf(PipelineEvent event) {
  using ros::console::levels::Level;
  switch (event) {
    case PipelineEvent::kMalformed:
      return {Level::Error, 1.0};
    case PipelineEvent::kMountMissing:
      return {Level::Error, 1.0};
    case PipelineEvent::kQueueFull:
      return {Level::Warn, 1.0};
    case PipelineEvent::kTfFailure:
      return {Level::Warn, 1.0};
    case PipelineEvent::kBadTransform:
      return {Level::Warn, 1.0};
    case PipelineEvent::kMountChanged:
      return {Level::Info, 5.0};         // a mount moving on /tf changes often
    case PipelineEvent::kTimeFallback:   // reported once by the pipeline
    case PipelineEvent::kStaticIgnored:  // once per frame
    case PipelineEvent::kTwoParents:     // once per frame
    case PipelineEvent::kStaleTf:        // once for stale tf, once for tf ahead
      return {Level::Warn, 0.0};
    case PipelineEvent::kTimeJump:  // each counted; a flood (a clock gone wrong) is not one line each
      return {Level::Warn, 1.0};
    case PipelineEvent::kMountFirst:
    case PipelineEvent::kTimingFound:  // once, and when it changes
      return {Level::Info, 0.0};
  }
  return {Level::Warn, 1.0};
}

/// The input topic (remappable): `scan` or `points`.
template <class Processor>
const char* inputTopic() {
  return std::is_same_v<Processor, ros_adapter::ScanProcessor> ? "scan" : "points";
}

/// [s] The clock scans wait on: ROS time when it is simulated (a paused or stepped `rosbag play
/// --clock` stops the wait too), else the wall clock.
double waitClock(const ros::WallTime& wall) {
  return ros::Time::isSimTime() ? ros::Time::now().toSec() : wall.toSec();
}

/// [s] CPU time of the calling thread.
double threadCpu() {
  timespec now{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

/// The share of the node's CPU the live timing check may take.
constexpr double kTimingCheckBudget = 0.05;
/// A check is taken when one costing this many times the costliest of late still fits the budget: a
/// check costs more as its history fills with partners and as their overlap varies, up to 2.4 times the
/// costliest before it (measured in timing_check_end.test, idle and loaded: 142 checks in 13 runs).
constexpr double kTimingCheckHeadroom = 3.0;

/// Adds the calling thread's CPU time from construction to destruction to a total.
class CpuSpent {
 public:
  explicit CpuSpent(double& total) : total_(total), start_(threadCpu()) {}
  ~CpuSpent() { total_ += threadCpu() - start_; }
  CpuSpent(const CpuSpent&) = delete;
  CpuSpent& operator=(const CpuSpent&) = delete;

 private:
  double& total_;
  double start_;
};

bool sameTiming(const core::TimingConfig& a, const core::TimingConfig& b) {
  return a.stamp_at == b.stamp_at && a.time_offset == b.time_offset && a.beam_order == b.beam_order &&
         a.scan_period == b.scan_period && a.use_scan_period == b.use_scan_period;
}

/// The node's dynamic_reconfigure config: each node type offers only the parameters its input reads.
template <class Processor>
using ConfigOf = std::conditional_t<std::is_same_v<Processor, ros_adapter::ScanProcessor>, DeskewScanConfig,
                                    DeskewCloudConfig>;

/// "name value" of each parameter whose value differs between two configs.
template <class Config>
std::string changes(const Config& before, const Config& after) {
  std::string text;
  for (const typename Config::AbstractParamDescriptionConstPtr& description :
       Config::__getParamDescriptions__()) {
    boost::any was;
    boost::any now;
    description->getValue(before, was);
    description->getValue(after, now);
    std::string value;
    if (const double* number = boost::any_cast<double>(&now)) {
      if (*number == boost::any_cast<double>(was))
        continue;
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%g", *number);
      value = buffer;
    } else if (const int* integer = boost::any_cast<int>(&now)) {
      if (*integer == boost::any_cast<int>(was))
        continue;
      value = std::to_string(*integer);
    } else if (const bool* flag = boost::any_cast<bool>(&now)) {
      if (*flag == boost::any_cast<bool>(was))
        continue;
      value = *flag ? "true" : "false";
    } else if (const std::string* string = boost::any_cast<std::string>(&now)) {
      if (*string == boost::any_cast<std::string>(was))
        continue;
      value = *string;
    }
    text += (text.empty() ? "" : ", ") + description->name + " " + value;
  }
  return text;
}

}  // namespace

/// The server and the last config taken (what a refused change goes back to).
template <class Processor>
struct DeskewNode<Processor>::Reconfigure {
  explicit Reconfigure(const ros::NodeHandle& private_nh) : server(private_nh) {}
  dynamic_reconfigure::Server<ConfigOf<Processor>> server;
  ConfigOf<Processor> taken;
  bool first = true;
};

template <class Processor>
DeskewNode<Processor>::DeskewNode(ros::NodeHandle nh, ros::NodeHandle private_nh, std::string name)
    : nh_(nh),
      private_nh_(private_nh),
      name_(std::move(name)),
      params_(ros_adapter::DeskewParams::load(private_nh)),
      input_queue_size_(params_.input_queue_size),
      pipeline_(
          params_, [this](const typename Pipeline::Result& result) { publish(result); },
          [this](PipelineEvent event, const std::string& text) { report(event, text); }) {
  last_diagnostics_ = last_tick_ = running_since_ = trigger_ = ros::WallTime::now();
  std::vector<std::string> given = ros_adapter::NodeHandleParams(private_nh_).names();
  given.erase(std::remove(given.begin(), given.end(), "diagnostic_period"), given.end());  // the Updater's
  for (const std::string& unknown : ros_adapter::DeskewParams::unknownNames(given))
    ROS_WARN("%s: ignoring unknown parameter ~%s", name_.c_str(), unknown.c_str());
  private_nh_.setParam("diagnostic_period", params_.diagnostics_period);  // read by the Updater
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh_, private_nh_, name_);
  diagnostics_->setHardwareID("none");
  // The Updater puts the node's name before each status name itself.
  diagnostics_->add("deskew", this, &DeskewNode::produceDiagnostics);
  if constexpr (std::is_same_v<Processor, ros_adapter::ScanProcessor>) {
    timing_check_ = std::make_unique<core::TimingCheck>(params_.timing);
    rotation_monitor_ = std::make_unique<core::RotationMonitor>(params_.timing);
    pipeline_.setCorrected([this](const typename Processor::Prepared& prepared,
                                  const mrpt::poses::CPose3D& mount) { checkTiming(prepared, mount); });
  }

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
    // Named after the input as remapped (the bag tool's names): two instances never collide.
    advertiseOutputs(nh_.resolveName(inputTopic<Processor>()), connect);
  }
  timer_ = nh_.createWallTimer(ros::WallDuration(kTimerPeriod), &DeskewNode::timerCallback, this);
  const std::string mode = params_.exact
                               ? "exact per-beam lookups"
                               : "knots every " + std::to_string(params_.deskew.knot_interval) + " s";
  const core::TimingConfig& timing = params_.timing;
  std::string outputs;
  for (const ros::Publisher& publisher : publishers_)
    outputs += (outputs.empty() ? "" : " and ") + publisher.getTopic();
  const std::string timed =
      std::is_same_v<Processor, ros_adapter::ScanProcessor>
          ? "stamp_at " + core::toString(timing.stamp_at) + ", time_offset " +
                ros_adapter::formatNumber(timing.time_offset) + " s, beam_order " +
                core::toString(timing.beam_order) + ", scan_period " +
                ros_adapter::formatNumber(timing.scan_period) +
                (timing.use_scan_period ? " s (always)" : " s (when time_increment and scan_time are 0)")
          : "time_offset " + ros_adapter::formatNumber(timing.time_offset) + " s, time field " +
                (params_.cloud_time.field.empty() ? std::string("found alone") : params_.cloud_time.field) +
                " (unit " + params_.cloud_time.unit + ", base " + params_.cloud_time.base + ")";
  ROS_INFO(
      "%s: %s -> %s; fixed_frame %s, base_frame %s; %s; reference %s, %s; tf_timeout %.3f s, on_tf_failure "
      "%s",
      name_.c_str(), nh_.resolveName(inputTopic<Processor>()).c_str(), outputs.c_str(),
      params_.fixed_frame.c_str(), params_.base_frame.c_str(), timed.c_str(),
      core::toString(params_.deskew.reference).c_str(), mode.c_str(), params_.tf_timeout,
      ros_adapter::toString(params_.on_tf_failure).c_str());
  // Last: from here on a reconfigure callback may change params_ (under mutex_) from another thread.
  // dynamic_reconfigure: the server reads the parameters as loaded above and calls back at once.
  reconfigure_ = std::make_unique<Reconfigure>(private_nh_);
  reconfigure_->server.setCallback([this](ConfigOf<Processor>& config, std::uint32_t /*level*/) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (reconfigure_->first)
      reconfigure_->taken = config;
    try {
      const ros_adapter::DeskewParams next = ros_adapter::DeskewParams::load(ConfigParams(config), params_);
      pipeline_.reconfigure(next);
      if (timing_check_ && !sameTiming(next.timing, params_.timing))
        timing_check_->reset(next.timing);
      if (rotation_monitor_ && !sameTiming(next.timing, params_.timing))
        rotation_monitor_->reset(next.timing);
      params_ = next;
      if (!reconfigure_->first) {
        const std::string changed = changes(reconfigure_->taken, config);
        ROS_INFO("%s: reconfigured: %s", name_.c_str(),
                 changed.empty() ? "nothing changed" : changed.c_str());
      }
      reconfigure_->taken = config;
    } catch (const core::InvalidInput& error) {
      ROS_ERROR("%s: reconfigure refused, keeping the running values: %s", name_.c_str(), error.what());
      config = reconfigure_->taken;  // the server publishes what is in force
    }
    reconfigure_->first = false;
  });
}

template <class Processor>
DeskewNode<Processor>::~DeskewNode() {
  reconfigure_.reset();  // no reconfigure callback while members go away
  {
    // No connect callback may touch a publisher or subscribe while members go away.
    std::lock_guard<std::mutex> lock(connect_mutex_);
    shutting_down_ = true;
    for (ros::Publisher& publisher : publishers_)
      publisher.shutdown();
  }
  timer_.stop();
  input_subscriber_.shutdown();
  tf_subscriber_.shutdown();
  tf_static_subscriber_.shutdown();
}

template <class Processor>
ros_adapter::DeskewParams DeskewNode<Processor>::params() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return params_;
}

template <class Processor>
const void* DeskewNode<Processor>::lastPublishedCloud() {
  return last_published_cloud.load();
}

template <class Processor>
double DeskewNode<Processor>::latencyP99() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latencyP99Locked();
}

template <class Processor>
double DeskewNode<Processor>::latencyP99Locked() const {
  if (latencies_.empty())
    return 0.0;
  std::vector<double> sorted = latencies_;
  const std::size_t rank = static_cast<std::size_t>(std::ceil(0.99 * sorted.size())) - 1;
  std::nth_element(sorted.begin(), sorted.begin() + rank, sorted.end());
  return sorted[rank];
}

template <class Processor>
typename DeskewNode<Processor>::Counters DeskewNode<Processor>::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return countersLocked();
}

template <class Processor>
typename DeskewNode<Processor>::Counters DeskewNode<Processor>::countersLocked() const {
  Counters counters = timing_;
  static_cast<ros_adapter::PipelineCounters&>(counters) = pipeline_.counters();
  return counters;
}

template <class Processor>
void DeskewNode<Processor>::advertiseOutputs(const std::string& input,
                                             const ros::SubscriberStatusCallback& connect) {
  if constexpr (std::is_same_v<Processor, ros_adapter::ScanProcessor>) {
    publishers_ = {
        nh_.advertise<sensor_msgs::LaserScan>(input + "_deskewed", 10, connect, connect),
        nh_.advertise<ros_adapter::DeskewedCloud>(input + "_deskewed_points", 10, connect, connect)};
  } else {
    publishers_ = {nh_.advertise<sensor_msgs::PointCloud2>(input + "_deskewed", 10, connect, connect)};
    if (params_.cloud_scan.enabled)
      publishers_.push_back(
          nh_.advertise<sensor_msgs::LaserScan>(input + "_deskewed_scan", 10, connect, connect));
  }
}

template <class Processor>
void DeskewNode<Processor>::connectCallback() {
  std::lock_guard<std::mutex> lock(connect_mutex_);
  if (shutting_down_)
    return;
  std::uint32_t subscribers = 0;
  for (const ros::Publisher& publisher : publishers_)
    subscribers += publisher.getNumSubscribers();
  const bool wanted = subscribers > 0;
  if (wanted && !input_subscriber_) {
    input_subscriber_ =
        nh_.subscribe<Message>(inputTopic<Processor>(), input_queue_size_, &DeskewNode::inputCallback, this,
                               ros::TransportHints().tcpNoDelay());
  } else if (!wanted && input_subscriber_) {
    input_subscriber_.shutdown();
  }
}

template <class Processor>
void DeskewNode<Processor>::inputCallback(const typename Message::ConstPtr& message) {
  const ros::WallTime arrival = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  const CpuSpent spent(callbacks_cpu_);
  trigger_ = arrival;
  try {
    pipeline_.add(message, waitClock(arrival));
  } catch (const std::exception& error) {  // never let an exception reach the manager
    ROS_ERROR_THROTTLE(1.0, "%s: error processing %ss: %s", name_.c_str(), Processor::kNoun, error.what());
  }
}

template <class Processor>
void DeskewNode<Processor>::tfCallback(const tf2_msgs::TFMessage::ConstPtr& message, bool is_static) {
  const ros::WallTime arrival = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  const CpuSpent spent(callbacks_cpu_);
  trigger_ = arrival;
  try {
    pipeline_.addTransforms(message->transforms, is_static, waitClock(arrival));
    // A scan the timing check holds until tf covers every alternative timing.
    if (timing_check_ && timing_check_->waiting() && timingCheckAffordable()) {
      timeCheck([&] { timing_check_->tryPending(pipeline_.tf().motion()); });
    }
  } catch (const std::exception& error) {  // never let an exception reach the manager
    ROS_ERROR_THROTTLE(1.0, "%s: error handling tf: %s", name_.c_str(), error.what());
  }
}

template <class Processor>
void DeskewNode<Processor>::showStatus(const std::optional<bool>& known, bool& reported, const char* name,
                                      Produce produce) {
  if (!known || *known == reported)
    return;
  if (*known)
    diagnostics_->add(name, this, produce);
  else
    diagnostics_->removeByName(name);
  reported = *known;
}

template <class Processor>
void DeskewNode<Processor>::timerCallback(const ros::WallTimerEvent& /*event*/) {
  bool diagnostics_due = false;
  std::optional<bool> timing_known;    // whether the timing check has a verdict, when diagnostics are due
  std::optional<bool> rotation_known;  // whether the rotation monitor has enough turning pairs, likewise
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const CpuSpent spent(callbacks_cpu_);
    const ros::WallTime now = ros::WallTime::now();
    trigger_ = now;
    // After a stall of this process (descheduled, swapped out, stopped), tf that came meanwhile may
    // not have been read yet: expire nothing until it has run for two timer periods again, so that
    // our own stall is never taken for tf being late.
    if ((now - last_tick_).toSec() > 2 * kTimerPeriod)
      running_since_ = now;
    last_tick_ = now;
    const bool settled = (now - running_since_).toSec() >= 2 * kTimerPeriod;
    try {
      if (settled)
        pipeline_.expire(waitClock(now));
      else
        pipeline_.serveReady(waitClock(now));
    } catch (const std::exception& error) {  // never let an exception reach the manager
      ROS_ERROR_THROTTLE(1.0, "%s: error processing %ss: %s", name_.c_str(), Processor::kNoun, error.what());
    }
    diagnostics_due = (now - last_diagnostics_).toSec() >= params_.diagnostics_period;
    if (diagnostics_due && timing_check_)
      timing_known = timing_check_->verdict().state != core::TimingCheck::State::kUnknown;
    if (diagnostics_due && rotation_monitor_)
      rotation_known = rotation_monitor_->agreement().turning_pairs >= core::ShapeConfig().min_pairs;
  }
  // The timing status appears once the robot has turned enough to tell, and goes when the check
  // starts over (the timing parameters changed). Outside mutex_: the Updater holds its own lock while
  // it calls the tasks, which take mutex_. Only this timer adds or removes the task.
  showStatus(timing_known, timing_reported_, "timing", &DeskewNode::produceTimingDiagnostics);
  // Likewise the status of tf's rotation against the scans.
  showStatus(rotation_known, rotation_reported_, "tf rotation", &DeskewNode::produceRotationDiagnostics);
  // On the wall clock: the Updater's own schedule is in ROS time, which stands still with a paused
  // bag and goes back when a bag loops (diagnostics then fell silent).
  if (diagnostics_due)
    diagnostics_->force_update();
}

template <class Processor>
void DeskewNode<Processor>::report(PipelineEvent event, const std::string& text) {
  const LogPolicy policy = policyOf(event);
  const ros::WallTime now = ros::WallTime::now();
  if (event == PipelineEvent::kMalformed || event == PipelineEvent::kTfFailure ||
      event == PipelineEvent::kMountMissing || event == PipelineEvent::kQueueFull)
    last_drop_ = text;  // every one, throttled or not: /diagnostics shows the newest
  const auto last = last_report_.find(event);
  if (policy.period > 0.0 && last != last_report_.end() && (now - last->second).toSec() < policy.period)
    return;
  last_report_[event] = now;
  // One macro per level: a rosconsole location keeps the level of its first use.
  if (policy.level == ros::console::levels::Error) {
    ROS_ERROR("%s: %s", name_.c_str(), text.c_str());
  } else if (policy.level == ros::console::levels::Warn) {
    ROS_WARN("%s: %s", name_.c_str(), text.c_str());
  } else {
    ROS_INFO("%s: %s", name_.c_str(), text.c_str());
  }
}

template <class Processor>
void DeskewNode<Processor>::publish(const typename Pipeline::Result& result) {
  const ros::WallTime start = ros::WallTime::now();
  // Shared pointers, never touched after publishing: same-type subscribers in the manager get them as is.
  if constexpr (std::is_same_v<Processor, ros_adapter::ScanProcessor>) {
    publishers_[0].publish(result.outputs.scan);
    last_published_cloud.store(result.outputs.cloud.get());
    publishers_[1].publish(result.outputs.cloud);
  } else {
    last_published_cloud.store(result.outputs.cloud.get());
    publishers_[0].publish(result.outputs.cloud);
    if (result.outputs.scan && publishers_.size() > 1)
      publishers_[1].publish(result.outputs.scan);
  }
  if (!result.corrected)
    return;
  const ros::WallTime done = ros::WallTime::now();
  const double processing = result.correction + (done - start).toSec();
  if (latencies_.size() < kLatencies) {
    latencies_.push_back((done - trigger_).toSec());
  } else {
    latencies_[next_latency_] = (done - trigger_).toSec();
    next_latency_ = (next_latency_ + 1) % kLatencies;
  }
  timing_.tf_wait_total += result.waited;
  timing_.tf_wait_max = std::max(timing_.tf_wait_max, result.waited);
  timing_.processing_total += processing;
  timing_.processing_max = std::max(timing_.processing_max, processing);
}

template <class Processor>
template <class Check>
void DeskewNode<Processor>::timeCheck(Check&& check) {
  const double before = check_cpu_;
  const std::size_t used_before = timing_check_->scans();
  {
    const CpuSpent spent(check_cpu_);
    check();
  }
  // The costliest of late decays by a tenth a check that used a scan. An attempt on a scan that tf does
  // not cover yet (with stamp_at: end, one per tf message while a scan waits) is cheap and does not wear
  // it down: it would let a real check by at a fraction of its cost.
  const bool used = timing_check_->scans() > used_before;
  largest_check_cpu_ = std::max(used ? 0.9 * largest_check_cpu_ : largest_check_cpu_, check_cpu_ - before);
}

template <class Processor>
bool DeskewNode<Processor>::timingCheckAffordable() const {
  // Within budget after one more check costing kTimingCheckHeadroom times the costliest of late
  // (timeCheck). Checks vary: the last one's cost alone let the share creep over the budget by a few
  // hundredths of a point under load, the costliest one's by half a point right after a check twice the
  // costliest before it (a short run, where one check is a tenth of the budget). The first check, its
  // cost unknown, is taken on the first scan.
  return check_cpu_ + kTimingCheckHeadroom * largest_check_cpu_ <= kTimingCheckBudget * callbacks_cpu_;
}

template <class Processor>
void DeskewNode<Processor>::checkTiming(const typename Processor::Prepared& prepared,
                                        const mrpt::poses::CPose3D& mount) {
  if constexpr (std::is_same_v<Processor, ros_adapter::ScanProcessor>) {
    if (rotation_monitor_) {
      try {  // a match every 2 s of scans: outside the timing check's budget
        rotation_monitor_->add(prepared.scan, mount, pipeline_.tf().motion());
      } catch (const std::exception& error) {  // the scan is published already: only the check loses
        ROS_ERROR_THROTTLE(10.0, "%s: rotation check: %s", name_.c_str(), error.what());
      }
    }
    if (!timing_check_)
      return;
    {
      const CpuSpent spent(check_cpu_);
      timing_check_->offer(prepared.scan);  // every scan: a copy, a shape partner of a later check
    }
    if (!timingCheckAffordable())
      return;
    timeCheck([&] {
      try {
        timing_check_->add(prepared.scan, mount, pipeline_.tf().motion());
      } catch (const std::exception& error) {  // the scan is published already: only the check loses
        ROS_ERROR_THROTTLE(10.0, "%s: timing check: %s", name_.c_str(), error.what());
      }
    });
  }
}

template <class Processor>
void DeskewNode<Processor>::produceTimingDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const core::TimingCheck::Verdict verdict = timing_check_->verdict();
  const bool warn = verdict.state == core::TimingCheck::State::kBetter ||
                    verdict.state == core::TimingCheck::State::kWorseThanRaw;
  status.summary(
      warn ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK,
      verdict.state == core::TimingCheck::State::kUnknown ? "not turned enough to tell" : verdict.message);
  status.add("pairs while turning", verdict.pairs);
  status.add("configured timing [mm]", 1e3 * verdict.configured);
  status.add("best alternative", verdict.best_name);
  status.add("best alternative [mm]", 1e3 * verdict.best);
  status.add("shape pairs", verdict.shape_pairs);
  status.add("shapes aligned raw [mm]", 1e3 * verdict.shape_raw);
  status.add("shapes aligned as configured [mm]", 1e3 * verdict.shape_configured);
  status.add("shapes best alternative", verdict.shape_best_name);
  status.add("shapes best alternative [mm]", 1e3 * verdict.shape_best);
  status.add("check CPU share [%]", 100.0 * check_cpu_ / std::max(1e-9, callbacks_cpu_));
}

template <class Processor>
void DeskewNode<Processor>::produceRotationDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const core::RotationAgreement agreement = rotation_monitor_->agreement();
  const std::vector<std::string> warnings = rotation_monitor_->warnings();
  char fits[160];
  std::snprintf(fits, sizeof fits,
                "tf's rotation fits the scans: scan matching sees %.2fx it (correlation %.2f)",
                agreement.scale, agreement.correlation);
  status.summary(
      warnings.empty() ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN,
      warnings.empty() ? std::string(fits) : warnings.front());
  status.add("scan matching / tf rotation", agreement.scale);
  status.add("rotation correlation", agreement.correlation);
  status.add("rotation pairs", agreement.pairs);
  status.add("rotation pairs turning", agreement.turning_pairs);
}

template <class Processor>
void DeskewNode<Processor>::produceDiagnostics(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Counters counters = countersLocked();
  const ros::WallTime now = ros::WallTime::now();
  const double elapsed = std::max(1e-9, (now - last_diagnostics_).toSec());
  const Counters& was = counters_at_last_diagnostics_;
  const std::uint64_t dropped =
      counters.dropped_invalid + counters.dropped_tf + counters.dropped_mount + counters.dropped_queue;
  const std::uint64_t dropped_before =
      was.dropped_invalid + was.dropped_tf + was.dropped_mount + was.dropped_queue;
  // The summary names the newest drop's cause (its whole text is "last drop").
  if (dropped > dropped_before || counters.passed_through > was.passed_through) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_drop_);
  } else if (counters.received > 0 && counters.published == 0) {
    // Input stopped, but nothing it brought was ever published: that stays a warning until one is.
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "none of the " + std::to_string(counters.received) + " " + std::string(Processor::kNoun) +
                       "s received was corrected" + (last_drop_.empty() ? "" : "; last drop: " + last_drop_));
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "ok");
  }
  status.add("input rate [Hz]", (counters.received - was.received) / elapsed);
  status.add("output rate [Hz]", (counters.published - was.published) / elapsed);
  for (const auto& [name, value] : ros_adapter::namedCounters(counters))
    status.add(name, value);
  status.add("waiting " + std::string(Processor::kNoun) + "s", pipeline_.waiting());
  status.add("last drop", last_drop_.empty() ? std::string("none") : last_drop_);
  const double done = std::max<std::uint64_t>(1, counters.published);
  status.add("tf wait mean [ms]", 1e3 * counters.tf_wait_total / done);
  status.add("tf wait max [ms]", 1e3 * counters.tf_wait_max);
  status.add("processing mean [us]", 1e6 * counters.processing_total / done);
  status.add("processing max [us]", 1e6 * counters.processing_max);
  status.add("latency p99 [ms]", 1e3 * latencyP99Locked());
  if (timing_check_) {
    status.add("timing check: scans", timing_check_->scans());
    const core::TimingCheck::Verdict verdict = timing_check_->verdict();
    status.add("timing check: pairs while turning", verdict.pairs);
    status.add("timing check: shape pairs", verdict.shape_pairs);
    status.add("timing check: CPU share [%]", 100.0 * check_cpu_ / std::max(1e-9, callbacks_cpu_));
  }
  counters_at_last_diagnostics_ = counters;
  last_diagnostics_ = now;
}

template class DeskewNode<ros_adapter::ScanProcessor>;
template class DeskewNode<ros_adapter::CloudProcessor>;

namespace {

template <class Processor>
class LiveNodeOf : public LiveNode {
 public:
  LiveNodeOf(const ros::NodeHandle& nh, const ros::NodeHandle& private_nh, const std::string& name)
      : node_(nh, private_nh, name) {}

 private:
  DeskewNode<Processor> node_;
};

}  // namespace

std::unique_ptr<LiveNode> startLiveNode(LiveInput input, const ros::NodeHandle& nh,
                                        const ros::NodeHandle& private_nh, const std::string& name) {
  if (input == LiveInput::kClouds)
    return std::make_unique<LiveNodeOf<ros_adapter::CloudProcessor>>(nh, private_nh, name);
  return std::make_unique<LiveNodeOf<ros_adapter::ScanProcessor>>(nh, private_nh, name);
}

int runLiveNode(LiveInput input, int argc, char** argv, const char* default_name) {
  ros::init(argc, argv, default_name);
  ros::NodeHandle nh, private_nh("~");
  try {
    const std::unique_ptr<LiveNode> node = startLiveNode(input, nh, private_nh, ros::this_node::getName());
    ros::spin();
  } catch (const core::InvalidInput& error) {
    ROS_FATAL("%s: invalid parameter %s", ros::this_node::getName().c_str(), error.what());
    return 1;
  }
  return 0;
}

}  // namespace lidar_deskew::node
