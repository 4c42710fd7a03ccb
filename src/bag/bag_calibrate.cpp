#include "lidar_deskew/bag/bag_calibrate.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "lidar_deskew/bag/bag_deskew.h"
#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/eval/shape_consistency.h"
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

/// The shape check's lines of describe() (Calibration::shapes_*), printed whatever was told.
std::string shapesText(const Calibration& calibration) {
  std::ostringstream text;
  if (calibration.shapes_checked) {
    text << "  shapes (scans up to 1.5 s apart whose turn differs, aligned by a free rigid scan match; "
         << "corrected / raw):\n"
         << "    the message's timing: " << eval::formatShapes(calibration.shapes_message) << "\n";
    if (calibration.shapes_estimate.pairs > 0)
      text << "    the estimated timing: " << eval::formatShapes(calibration.shapes_estimate) << "\n";
    text << "    rotation between consecutive scans, scan matching / tf: "
         << eval::formatRotation(calibration.rotation) << "\n";
    for (const std::string& warning : calibration.shape_warnings)
      text << "  warning: " << warning << "\n";
  } else {
    text << "  shapes: not checked (" << calibration.shape_error << ")\n";
  }
  return text.str();
}

}  // namespace

namespace {

/// One scan of the topic as the first pass sees it: where it is in the bag and whether it can serve.
struct ScanIndex {
  core::TimeNs stamp = 0;
  std::size_t frame = 0;  ///< index into the frames seen
  bool valid = false;
};

/// [rad/s] The base's turn rate from the stamp to the next scan's (at least 20 ms); 0 where tf does
/// not cover it.
double turnAt(const ros_adapter::TfFeed& tf, core::TimeNs stamp, core::TimeNs next) {
  try {
    return core::turnRate(tf.motion(), stamp, std::max(next, stamp + core::secondsToNs(0.02)));
  } catch (const core::MotionUnavailable&) {
    return 0.0;
  }
}

}  // namespace

std::vector<char> chooseScans(const std::vector<core::TimeNs>& stamps, const std::vector<double>& turn_rates,
                              std::size_t max_scans, double segment, double turning_rate) {
  std::vector<char> keep(stamps.size(), 1);
  if (stamps.size() <= max_scans || stamps.empty())
    return keep;
  // Segments of `segment` seconds, each scored by its turning scans and its changes of turn rate
  // (starting and stopping: what tells an offset), the best kept until max_scans.
  const core::TimeNs length = core::secondsToNs(segment);
  std::vector<std::pair<std::size_t, std::size_t>> segments;  // [first, end) scan indices
  for (std::size_t i = 0; i < stamps.size();) {
    std::size_t j = i;
    while (j < stamps.size() && stamps[j] - stamps[i] < length)
      ++j;
    segments.emplace_back(i, j);
    i = j;
  }
  std::vector<double> scores(segments.size(), 0.0);
  for (std::size_t k = 0; k < segments.size(); ++k) {
    for (std::size_t i = segments[k].first; i < segments[k].second; ++i) {
      scores[k] += std::abs(turn_rates[i]) >= turning_rate;
      if (i > segments[k].first && std::abs(turn_rates[i] - turn_rates[i - 1]) >= 0.5 * turning_rate)
        scores[k] += 1.0;
    }
    scores[k] /= std::max<std::size_t>(1, segments[k].second - segments[k].first);
  }
  std::vector<std::size_t> order(segments.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    order[k] = k;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return scores[a] > scores[b]; });
  keep.assign(stamps.size(), 0);
  std::size_t kept = 0;
  for (std::size_t k : order) {
    const std::size_t size = segments[k].second - segments[k].first;
    if (kept + size > max_scans)
      continue;
    std::fill(keep.begin() + segments[k].first, keep.begin() + segments[k].second, 1);
    kept += size;
  }
  return keep;
}

namespace {

/// The shape check of the estimate (Calibration::shapes_*): a timing that makes shapes worse than raw
/// is not told, with the figure; the rotation's verdict is kept for the user. Never throws: a check
/// that fails is said in `shape_error`.
void checkShapes(Calibration& calibration, std::vector<core::PlanarScan> scans, const mrpt::poses::CPose3D& mount,
                 const core::MotionSource& motion) {
  core::TimingEstimate& estimate = calibration.estimate;
  const core::ShapeConfig config;
  try {
    std::stable_sort(scans.begin(), scans.end(),
                     [](const core::PlanarScan& a, const core::PlanarScan& b) { return a.stamp < b.stamp; });
    const core::ShapeCheck check(std::move(scans), mount, motion, config);
    calibration.shapes_message = check.shapes(core::TimingConfig());
    const core::TimingConfig& judged = estimate.told ? estimate.timing : core::TimingConfig();
    if (estimate.told)
      calibration.shapes_estimate = check.shapes(judged);
    calibration.rotation = check.rotation(judged);
    calibration.shape_warnings = core::shapeWarnings(
        estimate.told ? calibration.shapes_estimate : calibration.shapes_message, calibration.rotation, config);
    calibration.shapes_checked = true;
  } catch (const std::exception& error) {
    calibration.shape_error = error.what();
    return;
  }
  const core::ShapeRatio& shapes = calibration.shapes_estimate;
  if (!estimate.told || shapes.pairs < config.min_pairs || !(shapes.ratio > config.max_ratio)) {
    // What was not told may be for tf's motion not fitting the scans: the refusal names it too.
    if (!estimate.offset_told) {
      for (const std::string& warning : calibration.shape_warnings)
        estimate.why += "; " + warning;
    }
    return;
  }
  std::ostringstream why;
  why << "corrected with the best timing found, scans a short time apart whose turn differs align worse "
      << "than raw ones (a free rigid scan match, which odometry between the scans does not enter): "
      << number(shapes.ratio, 2) << "x raw (quartiles " << number(shapes.ratio_low, 2) << "-"
      << number(shapes.ratio_high, 2) << ", " << shapes.pairs << " pairs)";
  for (const std::string& warning : calibration.shape_warnings)
    why << "; " << warning;
  why << ": the odometry or the laser's mount does not fit the scans; nothing to write";
  estimate.told = false;
  estimate.offset_told = false;
  estimate.cause = core::TimingCause::kWorseThanRaw;
  estimate.why = why.str();
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
  const auto say = [&options](const std::string& text) {
    if (options.progress)
      options.progress(text);
  };
  say("reading tf");
  std::map<ros_adapter::TfEvent, std::size_t> tf_events;
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      eval::loadRecordedTf(bag, options.input, options.params.fixed_frame, options.params.base_frame, nullptr,
                           {calibration.scan_topic}, &tf_events);
  calibration.tf_time_jumps = tf_events[ros_adapter::TfEvent::kTimeJump];
  calibration.tf_stale = tf_events[ros_adapter::TfEvent::kStaleIgnored];
  calibration.tf_ahead = tf_events[ros_adapter::TfEvent::kAheadIgnored];
  calibration.tf_refused = tf_events[ros_adapter::TfEvent::kBadTransform];
  const rosbag::TopicQuery topic(std::vector<std::string>{calibration.scan_topic});

  say("reading " + calibration.scan_topic + "'s stamps");
  // First pass: each scan's stamp, frame and validity only (the bag is streamed: memory does not grow
  // with the recording).
  std::vector<ScanIndex> index;
  std::vector<std::string> frames;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, topic)) {
    const auto scan = message.instantiate<sensor_msgs::LaserScan>();
    if (!scan)
      continue;
    ScanIndex entry;
    const core::PlanarScan planar = ros_adapter::fromMsg(*scan);
    entry.stamp = planar.stamp;
    try {
      core::validateScan(planar);
      entry.valid = true;
    } catch (const core::InvalidInput&) {
      // malformed: the node drops it too
    }
    const std::string frame = ros_adapter::normalizedFrame(scan->header.frame_id);
    entry.frame = std::find(frames.begin(), frames.end(), frame) - frames.begin();
    if (entry.frame == frames.size())
      frames.push_back(frame);
    index.push_back(entry);
  }
  // A frame that changes midway: the scans of the frame most of them have, the others named.
  std::vector<std::size_t> per_frame(frames.size(), 0);
  for (const ScanIndex& entry : index)
    per_frame[entry.frame] += entry.valid;
  const std::size_t frame =
      frames.empty() ? 0 : std::max_element(per_frame.begin(), per_frame.end()) - per_frame.begin();
  if (!frames.empty())
    calibration.frame = frames[frame];
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (f != frame) {
      calibration.other_frames.emplace_back(frames[f], per_frame[f]);
      calibration.other_frame_scans += per_frame[f];
    }
  }
  // Which scans the fit gets: at most max_scans, whole segments chosen by turning.
  std::vector<core::TimeNs> stamps;
  std::vector<std::size_t> candidates;
  for (std::size_t i = 0; i < index.size(); ++i) {
    if (!index[i].valid || index[i].frame != frame)
      continue;
    if (index[i].stamp == 0 ||
        tf->coverage(index[i].stamp, index[i].stamp) == ros_adapter::Coverage::kNever) {
      ++calibration.unusable_stamps;  // 0 or far from tf's time line (issue 23)
      continue;
    }
    candidates.push_back(i);
    stamps.push_back(index[i].stamp);
  }
  std::vector<double> turn_rates(stamps.size(), 0.0);
  if (stamps.size() > options.max_scans) {
    for (std::size_t k = 0; k < stamps.size(); ++k)
      turn_rates[k] = turnAt(*tf, stamps[k], k + 1 < stamps.size() ? stamps[k + 1] : stamps[k]);
  }
  const std::vector<char> chosen =
      chooseScans(stamps, turn_rates, options.max_scans, options.segment, options.fit.turning_rate);
  std::vector<char> wanted(index.size(), 0);
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    wanted[candidates[k]] = chosen[k];
    calibration.not_chosen += !chosen[k];
  }
  index.clear();
  index.shrink_to_fit();

  // Second pass: the chosen scans.
  say("reading " + std::to_string(candidates.size() - calibration.not_chosen) + " scans of " +
      calibration.scan_topic);
  std::vector<core::PlanarScan> scans;
  std::size_t position = 0;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, topic)) {
    const auto scan = message.instantiate<sensor_msgs::LaserScan>();
    if (!scan)
      continue;
    if (wanted[position++]) {
      scans.push_back(ros_adapter::fromMsg(*scan));
      calibration.beams = scans.back().ranges.size();
    }
  }
  if (scans.size() < 2) {
    const std::vector<std::string> topics = laserScanTopics(bag);
    std::string list;
    for (const std::string& name : topics)
      list += " " + name;
    throw std::runtime_error(options.input + ": fewer than 2 valid LaserScans on " + calibration.scan_topic +
                             " (LaserScan topics:" + list + ")");
  }
  std::string error;
  const auto mount = tf->mount(calibration.frame, error);
  if (!mount)
    throw std::runtime_error(options.input + ": no laser mount: " + error);
  std::vector<core::PlanarScan> shape_scans = scans;
  say("fitting the timing to " + std::to_string(scans.size()) + " scans");
  core::TimingFit fit(std::move(scans), *mount, tf->motion(), 0.0, options.fit);
  calibration.stamp_period = fit.nominalPeriod();
  calibration.stamp_period_sigma = fit.nominalPeriodSigma();
  calibration.estimate = core::estimateTiming(fit, options.fit);
  calibration.sweep = calibration.estimate.sweep;
  say("checking the scans' shapes");
  checkShapes(calibration, std::move(shape_scans), *mount, tf->motion());
  return calibration;
}

std::string describe(const Calibration& calibration) {
  const core::TimingEstimate& estimate = calibration.estimate;
  std::ostringstream text;
  text << calibration.scan_topic << " (frame " << calibration.frame << ", " << calibration.beams
       << " beams): " << estimate.scans << " scans, one every " << number(calibration.stamp_period * 1e3, 3)
       << " ms +- " << number(calibration.stamp_period_sigma * 1e3, 3) << " ms by their stamps\n";
  if (calibration.tf_time_jumps + calibration.tf_stale + calibration.tf_ahead + calibration.tf_refused > 0) {
    text << "  tf: " << calibration.tf_time_jumps
         << " time jumps (each cleared the tf before it: the scans before it go unused), "
         << calibration.tf_stale + calibration.tf_ahead << " transforms off the scans' time line left out ("
         << calibration.tf_stale << " behind, " << calibration.tf_ahead
         << " ahead: a second publisher on another clock?), " << calibration.tf_refused << " refused\n";
  }
  if (!calibration.other_frames.empty()) {
    text << "  the topic's frame_id changes midway: " << calibration.other_frame_scans
         << " scans are in another frame than " << calibration.frame << " (";
    for (std::size_t f = 0; f < calibration.other_frames.size(); ++f)
      text << (f ? ", " : "") << calibration.other_frames[f].first << ": "
           << calibration.other_frames[f].second;
    text << "); they are left out (each frame has its own mount), the " << calibration.frame
         << " scans calibrated\n";
  }
  if (calibration.not_chosen > 0)
    text << "  " << calibration.not_chosen << " scans left out to keep to "
         << estimate.scans + estimate.left_out << ": the 10 s segments that turn most are used\n";
  if (estimate.left_out > 0 || calibration.unusable_stamps > 0)
    text << "  left out: " << estimate.left_out
         << " scans tf does not cover (before its first sample or after "
         << "its last), " << calibration.unusable_stamps
         << " with a stamp tf cannot take (0, another clock)\n";
  text << "  motion: " << estimate.turning_scans << " scans turn at " << number(estimate.turning_rate, 2)
       << " rad/s or faster (fastest " << number(estimate.fastest_turn, 2) << " rad/s); " << estimate.pairs
       << " overlapping pairs with motion, " << estimate.turning_pairs << " with a turning scan, "
       << estimate.changing_pairs << " whose turn rates differ; odometry every "
       << number(estimate.odometry_interval * 1e3, 0) << " ms\n";
  if (!estimate.told) {
    text << shapesText(calibration) << "  nothing told (" << core::toString(estimate.cause)
         << "): " << estimate.why << "\n";
    return text.str();
  }
  const core::TimingConfig& timing = estimate.timing;
  if (estimate.offset_told) {
    text << "  first beam - stamp: " << number(estimate.time_offset * 1e3, 2) << " ms +- "
         << number(estimate.offset_sigma * 1e3, 2) << " ms (1 sigma, searched over +-"
         << number(estimate.search_range * 1e3, 0) << " ms, the score's minimum "
         << number(estimate.curve_depth * 100.0, 0) << " % below its median); the sweep lasts "
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
  if (estimate.period_given) {
    text << number(estimate.period * 1e3, 3)
         << " ms as given (the message's: " << number(estimate.message_period * 1e3, 3) << " ms)\n";
  } else if (estimate.period_estimated) {
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
  text << shapesText(calibration);
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
