#include "lidar_deskew/ros/deskew_params.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <stdexcept>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {
namespace {

constexpr double kNoBound = 0.0;

// The one table of parameters: name, type, default, unit, min, max, min exclusive, choices, live only,
// reconfigurable (may change while the node runs: cfg/DeskewScan.cfg, cfg/DeskewCloud.cfg), meaning, and
// the input it applies to when only one (scans or clouds). Bounds are inclusive unless min is exclusive;
// strings with choices take one of them.
const ParamSpec kSpecs[] = {
    {"fixed_frame", "string", "odom", "", kNoBound, kNoBound, false, "", false, false,
     "frame the base moves in"},
    {"base_frame", "string", "base_link", "", kNoBound, kNoBound, false, "", false, false,
     "the robot base; the mount is base_frame -> scan frame"},
    {"reference", "string", "start", "", kNoBound, kNoBound, false, "start|middle|end", false, true,
     "time every point is re-expressed at; outputs are stamped with it"},
    {"stamp_at", "string", "start", "", kNoBound, kNoBound, false, "start|end", false, true,
     "scans: which beam header.stamp refers to", Input::kScans},
    {"time_offset", "double", "0.0", "s", -10.0, 10.0, false, "", false, true,
     "added to header.stamp (before stamp_at): a fixed latency; scans and clouds; deskew_calibrate finds it"},
    {"beam_order", "string", "as_message", "", kNoBound, kNoBound, false, "as_message|reversed", false, true,
     "scans: the beams' order in time is their index order, or its reverse", Input::kScans},
    {"scan_period", "double", "0.0", "s", 0.0, 60.0, false, "", false, true,
     "revolution time when time_increment and scan_time are 0; 0 = none", Input::kScans},
    {"use_scan_period", "bool", "false", "", kNoBound, kNoBound, false, "", false, true,
     "scans: beam spacing from scan_period even when the message gives time_increment or scan_time",
     Input::kScans},
    {"max_sweep_duration", "double", "1.0", "s", 0.0, 60.0, true, "", false, false,
     "longer sweeps are malformed"},
    {"time_field", "string", "", "", kNoBound, kNoBound, false, "", false, false,
     "clouds: the per-point time field; empty = t, time, timestamp, time_stamp, offset_time, stamps",
     Input::kClouds},
    {"time_unit", "string", "auto", "", kNoBound, kNoBound, false, "auto|s|ms|us|ns", false, false,
     "clouds: unit of the time field; auto = decided from its values", Input::kClouds},
    {"time_base", "string", "auto", "", kNoBound, kNoBound, false, "auto|header|absolute", false, false,
     "clouds: time values are offsets from header.stamp or absolute; auto = decided from its values",
     Input::kClouds},
    {"azimuth_timing", "bool", "false", "", kNoBound, kNoBound, false, "", false, false,
     "clouds without a time field: time each point from its azimuth (spinning sensors); false = drop them",
     Input::kClouds},
    {"azimuth_direction", "string", "cw", "", kNoBound, kNoBound, false, "cw|ccw", false, false,
     "clouds timed by azimuth: the spin seen from above (Velodyne, Ouster: cw)", Input::kClouds},
    {"azimuth_period", "double", "0.1", "s", 0.0, 60.0, true, "", false, false,
     "clouds timed by azimuth: one revolution (10 Hz: 0.1)", Input::kClouds},
    {"azimuth_stamp_at", "string", "start", "", kNoBound, kNoBound, false, "start|end", false, false,
     "clouds timed by azimuth: header.stamp is the first or the last point's time", Input::kClouds},
    {"cloud_scan", "bool", "false", "", kNoBound, kNoBound, false, "", false, false,
     "clouds: also a planar LaserScan <points>_deskewed_scan of the corrected points in the height band",
     Input::kClouds},
    {"scan_height_min", "double", "-0.1", "m", -100.0, 100.0, false, "", false, true,
     "clouds: the band's lowest z in the cloud's frame", Input::kClouds},
    {"scan_height_max", "double", "0.1", "m", -100.0, 100.0, false, "", false, true,
     "clouds: the band's highest z in the cloud's frame", Input::kClouds},
    {"scan_angle_min", "double", "-3.14159", "rad", -3.15, 3.15, false, "", false, true,
     "clouds: the planar scan's first bearing", Input::kClouds},
    {"scan_angle_max", "double", "3.14159", "rad", -3.15, 3.15, false, "", false, true,
     "clouds: the planar scan's last bearing", Input::kClouds},
    {"scan_angle_increment", "double", "0.00436332", "rad", 1e-5, 1.0, false, "", false, true,
     "clouds: the planar scan's bin width (0.25 deg)", Input::kClouds},
    {"scan_range_max", "double", "100.0", "m", 0.0, 10000.0, true, "", false, true,
     "clouds: the planar scan's range_max; farther points are left out", Input::kClouds},
    {"knot_interval", "double", "0.005", "s", 1e-5, 1.0, false, "", false, false,
     "spacing of tf lookups across the sweep (plus tf's own sample times)"},
    {"interpolation", "string", "twist", "", kNoBound, kNoBound, false, "twist|linear", false, false,
     "motion between tf samples: twist = each interval's body twist, changing as its neighbours' "
     "show where the samples are exact (exact on arcs, third order between samples); linear = tf2's own "
     "straight line"},
    {"fit_look_ahead", "double", "0.0", "s", 0.0, 1.0, false, "", false, false,
     "interpolation twist: the fit also reads tf's samples up to this long after the sweep's end, and "
     "live the scan waits for them (up to tf_timeout); 0 = up to the sample closing the sweep. "
     "deskew_bag: 1 unless given"},
    {"exact", "bool", "false", "", kNoBound, kNoBound, false, "", false, false,
     "one tf lookup per beam (verification, benchmarks)"},
    {"tf_timeout", "double", "0.2", "s", 0.0, 60.0, false, "", false, true,
     "longest wait for tf to cover a sweep's last beam (offline, the recording's tf decides)"},
    {"on_tf_failure", "string", "drop", "", kNoBound, kNoBound, false, "drop|pass_through", false, true,
     "what happens to a scan tf does not cover"},
    {"max_tf_gap", "double", "0.5", "s", 0.0, 60.0, false, "", false, true,
     "refuse sweeps tf interpolates across a longer gap; 0 = never"},
    {"max_extrapolation", "double", "0.0", "s", 0.0, 1.0, false, "", true, true,
     "after tf_timeout without tf, extrapolate at most this far instead of failing; 0 = never"},
    {"queue_size", "int", "10", "scans", 1.0, 100000.0, false, "", false, true,
     "scans waiting for tf at most"},
    {"input_queue_size", "int", "10", "scans", 1.0, 100000.0, false, "", true, false,
     "roscpp's queue of the input subscription (losses there count as lost upstream)"},
    {"rebin_min_gap", "double", "0.05", "m", 0.0, 100.0, false, "", false, true,
     "contour join distance, constant part", Input::kScans},
    {"rebin_gap_factor", "double", "5.0", "", 0.0, 1000.0, false, "", false, true,
     "contour join distance per (range x angle increment)", Input::kScans},
    {"diagnostics_period", "double", "1.0", "s", 0.0, 3600.0, true, "", true, true, "period of /diagnostics"},
};

const ParamSpec& specOf(const std::string& name) {
  for (const ParamSpec& spec : kSpecs) {
    if (name == spec.name)
      return spec;
  }
  throw std::logic_error("no parameter " + name);
}

void checkNumber(const std::string& name, double value) {
  const ParamSpec& spec = specOf(name);
  const bool above_min = spec.min_exclusive ? value > spec.min : value >= spec.min;
  if (!std::isfinite(value) || !above_min || value > spec.max)
    throw core::InvalidInput(name, "must be in " + spec.bounds() +
                                       (*spec.unit ? std::string(" ") + spec.unit : "") + ", got " +
                                       std::to_string(value));
}

void checkChoice(const std::string& name, const std::string& value) {
  const std::string choices = specOf(name).choices;
  if (choices.empty())
    return;
  if (("|" + choices + "|").find("|" + value + "|") == std::string::npos)
    throw core::InvalidInput(name, "must be one of " + choices + ", got '" + value + "'");
}

/// Edit distance (insertions, deletions, substitutions) between two names.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j)
    row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// The names of the parameters whose `flag` is set.
std::vector<std::string> namesWhere(bool ParamSpec::*flag) {
  std::vector<std::string> names;
  for (const ParamSpec& spec : kSpecs) {
    if (spec.*flag)
      names.push_back(spec.name);
  }
  return names;
}

}  // namespace

std::string ParamSpec::bounds() const {
  const std::string kind = type;
  if (kind == "double" || kind == "int")
    return std::string(min_exclusive ? "(" : "[") + formatNumber(min) + ", " + formatNumber(max) + "]";
  std::string text = choices;
  for (std::size_t bar = text.find('|'); bar != std::string::npos; bar = text.find('|', bar))
    text.replace(bar, 1, ", ");
  return text;
}

const std::vector<ParamSpec>& DeskewParams::specs() {
  static const std::vector<ParamSpec> specs(std::begin(kSpecs), std::end(kSpecs));
  return specs;
}

const std::vector<std::string>& DeskewParams::names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> all;
    for (const ParamSpec& spec : kSpecs)
      all.push_back(spec.name);
    return all;
  }();
  return names;
}

const std::vector<std::string>& DeskewParams::liveOnlyNames() {
  static const std::vector<std::string> names = namesWhere(&ParamSpec::live_only);
  return names;
}

const std::vector<std::string>& DeskewParams::reconfigurableNames() {
  static const std::vector<std::string> names = namesWhere(&ParamSpec::reconfigurable);
  return names;
}

std::vector<std::string> DeskewParams::reconfigurableNames(Input node) {
  std::vector<std::string> names;
  for (const ParamSpec& spec : kSpecs) {
    if (spec.reconfigurable && spec.readBy(node))
      names.push_back(spec.name);
  }
  return names;
}

std::string toString(OnTfFailure value) {
  return value == OnTfFailure::kDrop ? "drop" : "pass_through";
}

DeskewParams DeskewParams::load(const ParamSource& source) {
  return load(source, DeskewParams());
}

DeskewParams DeskewParams::load(const ParamSource& source, const DeskewParams& base) {
  DeskewParams params = base;
  std::string text;
  source.get("fixed_frame", params.fixed_frame);
  source.get("base_frame", params.base_frame);
  params.fixed_frame = normalizedFrame(params.fixed_frame);
  params.base_frame = normalizedFrame(params.base_frame);
  if (source.get("reference", text)) {
    checkChoice("reference", text);
    params.deskew.reference = core::parseReference(text);
  }
  if (source.get("stamp_at", text)) {
    checkChoice("stamp_at", text);
    params.timing.stamp_at = core::parseStampAt(text);
  }
  source.get("time_offset", params.timing.time_offset);
  if (source.get("beam_order", text)) {
    checkChoice("beam_order", text);
    params.timing.beam_order = core::parseBeamOrder(text);
  }
  source.get("scan_period", params.timing.scan_period);
  source.get("use_scan_period", params.timing.use_scan_period);
  source.get("max_sweep_duration", params.timing.max_sweep_duration);
  source.get("time_field", params.cloud_time.field);
  if (source.get("time_unit", text)) {
    checkChoice("time_unit", text);
    params.cloud_time.unit = text;
  }
  if (source.get("time_base", text)) {
    checkChoice("time_base", text);
    params.cloud_time.base = text;
  }
  source.get("azimuth_timing", params.azimuth.enabled);
  if (source.get("azimuth_direction", text)) {
    checkChoice("azimuth_direction", text);
    params.azimuth.direction = text;
  }
  source.get("azimuth_period", params.azimuth.period);
  if (source.get("azimuth_stamp_at", text)) {
    checkChoice("azimuth_stamp_at", text);
    params.azimuth.stamp_at = text;
  }
  source.get("cloud_scan", params.cloud_scan.enabled);
  source.get("scan_height_min", params.cloud_scan.height_min);
  source.get("scan_height_max", params.cloud_scan.height_max);
  source.get("scan_angle_min", params.cloud_scan.angle_min);
  source.get("scan_angle_max", params.cloud_scan.angle_max);
  source.get("scan_angle_increment", params.cloud_scan.angle_increment);
  source.get("scan_range_max", params.cloud_scan.range_max);
  source.get("knot_interval", params.deskew.knot_interval);
  if (source.get("interpolation", text)) {
    checkChoice("interpolation", text);
    params.deskew.interpolation = core::parseInterpolation(text);
  }
  source.get("fit_look_ahead", params.deskew.fit_look_ahead);
  source.get("exact", params.exact);
  if (params.exact)
    params.deskew.knot_interval = 0.0;
  source.get("tf_timeout", params.tf_timeout);
  if (source.get("on_tf_failure", text)) {
    checkChoice("on_tf_failure", text);
    params.on_tf_failure = text == "drop" ? OnTfFailure::kDrop : OnTfFailure::kPassThrough;
  }
  source.get("max_tf_gap", params.max_tf_gap);
  source.get("max_extrapolation", params.max_extrapolation);
  source.get("queue_size", params.queue_size);
  source.get("input_queue_size", params.input_queue_size);
  source.get("rebin_min_gap", params.rebin.min_gap);
  source.get("rebin_gap_factor", params.rebin.gap_factor);
  source.get("diagnostics_period", params.diagnostics_period);
  params.validate();
  return params;
}

std::vector<std::string> DeskewParams::unknownNames(const std::vector<std::string>& given) {
  std::vector<std::string> unknown;
  const auto& known = names();
  for (const std::string& name : given) {
    if (std::find(known.begin(), known.end(), name) != known.end())
      continue;
    if (name == "smoothing_window") {  // removed (CHANGELOG, Forthcoming)
      unknown.push_back(name + " (no longer used: noisy odometry is averaged over the sweep only)");
      continue;
    }
    const std::string closest = closestName(name, known);
    unknown.push_back(closest.empty() ? name : name + " (did you mean " + closest + "?)");
  }
  return unknown;
}

std::string closestName(const std::string& name, const std::vector<std::string>& candidates) {
  std::string closest;
  std::size_t best = 3;  // at most two edits make a misspelling
  for (const std::string& candidate : candidates) {
    const std::size_t distance = editDistance(name, candidate);
    if (distance < best) {
      best = distance;
      closest = candidate;
    }
  }
  return closest;
}

void DeskewParams::validate() const {
  if (fixed_frame.empty())
    throw core::InvalidInput("fixed_frame", "must not be empty");
  if (base_frame.empty())
    throw core::InvalidInput("base_frame", "must not be empty");
  if (fixed_frame == base_frame)
    throw core::InvalidInput("base_frame", "must differ from fixed_frame");
  checkNumber("scan_period", timing.scan_period);
  checkNumber("time_offset", timing.time_offset);
  checkNumber("max_sweep_duration", timing.max_sweep_duration);
  if (!exact && deskew.knot_interval == 0.0)
    throw core::InvalidInput("knot_interval", "must be > 0; set exact: true for per-beam lookups");
  if (!exact)
    checkNumber("knot_interval", deskew.knot_interval);
  else if (deskew.knot_interval != 0.0)
    throw core::InvalidInput("knot_interval", "must be 0 with exact: true");
  checkNumber("fit_look_ahead", deskew.fit_look_ahead);
  checkNumber("tf_timeout", tf_timeout);
  checkNumber("max_tf_gap", max_tf_gap);
  checkNumber("max_extrapolation", max_extrapolation);
  checkNumber("queue_size", queue_size);
  checkNumber("input_queue_size", input_queue_size);
  checkNumber("rebin_min_gap", rebin.min_gap);
  checkNumber("rebin_gap_factor", rebin.gap_factor);
  checkNumber("diagnostics_period", diagnostics_period);
  checkNumber("azimuth_period", azimuth.period);
  if (azimuth.enabled && azimuth.period > timing.max_sweep_duration)
    throw core::InvalidInput("azimuth_period", "must be at most max_sweep_duration with azimuth_timing on");
  checkNumber("scan_height_min", cloud_scan.height_min);
  checkNumber("scan_height_max", cloud_scan.height_max);
  checkNumber("scan_angle_min", cloud_scan.angle_min);
  checkNumber("scan_angle_max", cloud_scan.angle_max);
  checkNumber("scan_angle_increment", cloud_scan.angle_increment);
  checkNumber("scan_range_max", cloud_scan.range_max);
  // The core's own checks (the same bounds or wider).
  azimuth.validate();
  timing.validate();
  deskew.validate();
  rebin.validate();
}

}  // namespace lidar_deskew::ros_adapter
