#include "lidar_deskew/bag/bag_calibrate.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "lidar_deskew/bag/bag_deskew.h"
#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::bag {
namespace {

std::string number(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

std::string consistency(const core::ConsistencySummary& summary) {
  if (summary.pairs == 0)
    return "-";
  return number(summary.mean * 1e3, 2) + " mm (spread " + number(summary.spread * 1e3, 2) + ", median " +
         number(summary.median * 1e3, 2) + ", " + std::to_string(summary.pairs) + " pairs)";
}

}  // namespace

Calibration calibrateBag(const CalibrateOptions& options) {
  rosbag::Bag bag = ros_adapter::openBagForReading(options.input);
  Calibration calibration;
  calibration.scan_topic = options.scan_topic;
  if (calibration.scan_topic.empty()) {
    const std::vector<std::string> topics = laserScanTopics(bag);
    if (topics.size() != 1) {
      std::string list;
      for (const std::string& topic : topics)
        list += " " + topic;
      throw std::runtime_error(options.input + ": " +
                               (topics.empty()
                                    ? std::string("has no LaserScan topic")
                                    : "has several LaserScan topics; choose one with --scan-topic:" + list));
    }
    calibration.scan_topic = topics.front();
  }
  std::vector<core::PlanarScan> scans;
  for (const rosbag::MessageInstance& message :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{calibration.scan_topic}))) {
    const auto scan = message.instantiate<sensor_msgs::LaserScan>();
    if (!scan)
      continue;
    core::PlanarScan planar = ros_adapter::fromMsg(*scan);
    try {
      core::validateScan(planar);
    } catch (const core::InvalidInput&) {
      continue;  // malformed: the node drops it too
    }
    if (calibration.frame.empty())
      calibration.frame = ros_adapter::normalizedFrame(scan->header.frame_id);
    calibration.beams = planar.ranges.size();
    scans.push_back(std::move(planar));
  }
  if (scans.size() < 2) {
    const std::vector<std::string> topics = laserScanTopics(bag);
    std::string list;
    for (const std::string& topic : topics)
      list += " " + topic;
    throw std::runtime_error(options.input + ": fewer than 2 valid LaserScans on " + calibration.scan_topic +
                             " (LaserScan topics:" + list + ")");
  }
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      eval::loadRecordedTf(bag, options.input, options.params.fixed_frame, options.params.base_frame);
  // Stamps tf cannot take (0, far from tf's time line: uninitialised) are left out (issue 23).
  calibration.unusable_stamps = eval::dropStampsTfCannotTake(scans, *tf);
  std::string error;
  const auto mount = tf->mount(calibration.frame, error);
  if (!mount)
    throw std::runtime_error(options.input + ": no laser mount: " + error);
  core::TimingFit fit(std::move(scans), *mount, tf->motion(), 0.0, options.fit);
  calibration.stamp_period = fit.nominalPeriod();
  calibration.stamp_period_sigma = fit.nominalPeriodSigma();
  calibration.estimate = core::estimateTiming(fit, options.fit);
  calibration.sweep = calibration.estimate.sweep;
  return calibration;
}

std::string describe(const Calibration& calibration) {
  const core::TimingEstimate& estimate = calibration.estimate;
  std::ostringstream text;
  text << calibration.scan_topic << " (frame " << calibration.frame << ", " << calibration.beams
       << " beams): " << estimate.scans << " scans, one every " << number(calibration.stamp_period * 1e3, 3)
       << " ms +- " << number(calibration.stamp_period_sigma * 1e3, 3) << " ms by their stamps\n";
  if (estimate.left_out > 0 || calibration.unusable_stamps > 0)
    text << "  left out: " << estimate.left_out << " scans tf does not cover (before its first sample or after "
         << "its last), " << calibration.unusable_stamps << " with a stamp tf cannot take (0, another clock)\n";
  text << "  motion: " << estimate.turning_scans << " scans turn at " << number(estimate.turning_rate, 2)
       << " rad/s or faster (fastest " << number(estimate.fastest_turn, 2) << " rad/s); " << estimate.pairs
       << " overlapping pairs with motion, " << estimate.turning_pairs << " with a turning scan, "
       << estimate.changing_pairs << " whose turn rates differ; odometry every "
       << number(estimate.odometry_interval * 1e3, 0) << " ms\n";
  if (!estimate.told) {
    text << "  nothing told (" << core::toString(estimate.cause) << "): " << estimate.why << "\n";
    return text.str();
  }
  const core::TimingConfig& timing = estimate.timing;
  if (estimate.offset_told) {
    text << "  first beam - stamp: " << number(estimate.time_offset * 1e3, 2) << " ms +- "
         << number(estimate.offset_sigma * 1e3, 2) << " ms (1 sigma, searched over +-"
         << number(estimate.search_range * 1e3, 0) << " ms); the sweep lasts "
         << number(calibration.sweep * 1e3, 2) << " ms";
    if (timing.stamp_at == core::StampAt::kEnd)
      text << ": stamped at the end of the sweep";
    else if (timing.time_offset == 0.0)
      text << ": stamped at the first beam, as ROS says";
    text << "\n";
  } else {
    text << "  first beam - stamp: not told (" << core::toString(estimate.cause) << "): " << estimate.why
         << ". The message's offset is kept\n";
  }
  text << "  beam order: "
       << (timing.beam_order == core::BeamOrder::kReversed ? "reversed" : "as the message says")
       << " (held in " << number(estimate.order_confidence * 100.0, 0) << " % of resamples of "
       << estimate.block_scans << "-scan blocks)\n";
  text << "  period: ";
  if (estimate.period_estimated) {
    text << number(estimate.period * 1e3, 3) << " ms +- " << number(estimate.period_sigma * 1e3, 3)
         << " ms from the stamps; the message's "
         << (estimate.message_period > 0.0 ? "(" + number(estimate.message_period * 1e3, 3) + " ms) disagrees"
                                           : "is 0 (time_increment and scan_time)")
         << " (held in " << number(estimate.period_confidence * 100.0, 0) << " % of resamples)\n";
  } else {
    text << number(estimate.message_period * 1e3, 3)
         << " ms as the message says (stamps: " << number(calibration.stamp_period * 1e3, 3) << " ms)\n";
  }
  text << "  consistency (robust point-to-line distance between overlapping scans):\n"
       << "    raw (every beam at the stamp): " << consistency(estimate.raw) << "\n"
       << "    corrected, the message's timing: " << consistency(estimate.before) << "\n"
       << "    corrected, the estimated timing: " << consistency(estimate.after) << "\n";
  if (!estimate.offset_told)
    text << (estimate.changed
                 ? "  the message's beam order or period is wrong: use the parameters below (the offset "
                   "is the message's)\n"
                 : "  the message's beam order and period fit; its offset could not be checked\n");
  else
    text << (estimate.changed ? "  the message's timing is wrong: use the parameters below\n"
                              : "  the message's timing fits: nothing to change\n");
  return text.str();
}

void writeCurve(const Calibration& calibration, const std::string& path) {
  std::ofstream out(path);
  if (!out)
    throw std::runtime_error(path + ": cannot write");
  out << "# deskew_calibrate's score of " << calibration.scan_topic
      << " against the offset (first beam - stamp), the chosen beam order and period\n"
      << "search,offset_s,score_m\n";
  for (const auto& [offset, score] : calibration.estimate.coarse_curve)
    out << "coarse," << number(offset, 6) << "," << number(score, 6) << "\n";
  for (const auto& [offset, score] : calibration.estimate.fine_curve)
    out << "fine," << number(offset, 6) << "," << number(score, 6) << "\n";
  if (!out.flush())
    throw std::runtime_error(path + ": cannot write");
}

void writeTimingParams(const Calibration& calibration, const std::string& bag, const std::string& path) {
  const core::TimingEstimate& estimate = calibration.estimate;
  const core::TimingConfig& timing = estimate.timing;
  std::ofstream out(path);
  if (!out)
    throw std::runtime_error(path + ": cannot write");
  out << "# lidar_deskew timing of " << calibration.scan_topic << " (frame " << calibration.frame
      << "), estimated by deskew_calibrate\n# from " << bag << ": " << estimate.scans << " scans, "
      << estimate.pairs << " overlapping pairs, " << estimate.turning_scans << " turning.\n"
      << (estimate.offset_told ? "# first beam - stamp " + number(estimate.time_offset * 1e3, 2) + " +- " +
                                     number(estimate.offset_sigma * 1e3, 2) + " ms"
                               : "# first beam - stamp NOT TOLD (" + core::toString(estimate.cause) +
                                     "): the message's offset is kept")
      << "; overlapping scans "
      << (estimate.before.pairs ? number(estimate.before.mean * 1e3, 2) + " mm" : std::string("-"))
      << " apart with the message's timing, " << number(estimate.after.mean * 1e3, 2) << " mm with this.\n"
      << "# Use: roslaunch lidar_deskew deskew.launch params:=" << path << "\n"
      << "#      rosrun lidar_deskew deskew_bag IN.bag OUT.bag --params " << path << "\n";
  if (estimate.offset_told) {
    out << "stamp_at: " << core::toString(timing.stamp_at) << "\n";
    out << "time_offset: " << number(timing.time_offset, 5) << "  # [s]\n";
  } else {
    out << "# stamp_at, time_offset: not written (the recording cannot tell them): yours or the defaults "
           "hold\n";
  }
  out << "beam_order: " << core::toString(timing.beam_order) << "\n";
  if (estimate.period_estimated) {
    out << "scan_period: " << number(timing.scan_period, 6) << "  # [s] one revolution\n";
    out << "use_scan_period: " << (timing.use_scan_period ? "true" : "false") << "\n";
  }
  if (!out.flush())
    throw std::runtime_error(path + ": cannot write");
}

}  // namespace lidar_deskew::bag
