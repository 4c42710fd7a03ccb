#include "lidar_deskew/eval/calibration_runs.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "lidar_deskew/eval/evaluate.h"
#include "lidar_deskew/sim/sim_bag.h"

namespace lidar_deskew::eval {
namespace {

sim::TimingFault fault(double stamp_error, bool reversed = false, double factor = 1.0,
                       bool zero_scan_time = false) {
  sim::TimingFault made;
  made.stamp_error = stamp_error;
  made.reversed = reversed;
  made.time_increment_factor = factor;
  made.zero_scan_time = zero_scan_time;
  return made;
}

double atEnd(const std::string& scenario) {
  return sim::TimingFault::stampedAtEnd(sim::findScenario(scenario).lidar).stamp_error;
}

}  // namespace

std::vector<CalibrationCase> calibrationCases() {
  const std::string lds = "LDS-01/normal/turns", lds_high = "LDS-01/high/turns",
                    ild = "ILD26TRI/normal/turns", ild_high = "ILD26TRI/high/turns",
                    utm = "UTM-30LX/normal/turns", utm_high = "UTM-30LX/high/turns",
                    utm270 = "UTM-30LX-270/normal/turns", utm270_high = "UTM-30LX-270/high/turns";
  return {
      {ild, "none", fault(0.0), 1},
      {utm270, "none", fault(0.0), 2},
      {lds, "stamped at the end", fault(atEnd(lds)), 3},
      {ild_high, "stamped at the end", fault(atEnd(ild_high)), 4},
      {utm, "stamped at the end", fault(atEnd(utm)), 5},
      {lds_high, "stamp 10 ms late", fault(0.010), 6},
      {ild, "stamp 25 ms early", fault(-0.025), 7},
      {utm_high, "stamp 40 ms late", fault(0.040), 8},
      {utm270_high, "stamp 60 ms early", fault(-0.060), 9},
      {ild_high, "stamp 60 ms late", fault(0.060), 10},
      {lds, "stamp 45 ms early", fault(-0.045), 11},
      {lds, "reversed", fault(0.0, true), 12},
      {ild, "reversed", fault(0.0, true), 13},
      {utm270, "reversed", fault(0.0, true), 14},
      {lds_high, "reversed, stamped at the end", fault(atEnd(lds_high), true), 15},
      {ild_high, "reversed, stamp 30 ms late", fault(0.030, true), 16},
      {ild_high, "time_increment and scan_time 0", fault(0.0, false, 0.0, true), 17},
      {lds, "time_increment and scan_time 0, stamp 20 ms late", fault(0.020, false, 0.0, true), 18},
      {utm, "time_increment and scan_time 0", fault(0.0, false, 0.0, true), 19},
      {ild, "time_increment x 0.5", fault(0.0, false, 0.5), 20},
      {utm_high, "time_increment x 2", fault(0.0, false, 2.0), 21},
      {ild, "time_increment x 1000 (ms as s)", fault(0.0, false, 1000.0), 22},
      {lds, "as the LDS-01 driver: reversed, stamped at the end, time_increment x 0.054",
       fault(atEnd(lds), true, 0.054), 23},
      {utm270_high, "time_increment 0 (scan_time right), stamp 15 ms early", fault(-0.015, false, 0.0), 24},
  };
}

CalibrationRun runCalibrationCase(const CalibrationCase& recording, const std::string& directory) {
  const std::string stem = directory + "/calibration_" + std::to_string(recording.seed);
  const std::string bag_path = stem + ".bag", truth_path = stem + ".truth";
  sim::SimBagOptions options;
  options.noise = true;
  options.seed = recording.seed;
  options.timing_fault = recording.timing_fault;
  const sim::Scenario scenario = sim::findScenario(recording.scenario);
  sim::writeSimulationBag(scenario, options, bag_path, truth_path);
  const sim::Truth truth = sim::readTruth(truth_path);

  CalibrationRun run;
  run.recording = recording;
  bag::CalibrateOptions calibrate;
  calibrate.input = bag_path;
  calibrate.scan_topic = "/scan";
  run.calibration = bag::calibrateBag(calibrate);
  run.true_offset = truth.timeOffset();
  run.true_reversed = truth.timing_fault.reversed;
  const core::TimingEstimate& estimate = run.calibration.estimate;
  run.offset_error = estimate.time_offset - run.true_offset;
  run.order_right = (estimate.timing.beam_order == core::BeamOrder::kReversed) == run.true_reversed;

  EvaluateOptions score;
  const auto cloudRms = [&](const core::TimingConfig& timing, Evaluation* kept) {
    score.timing = timing;
    const Evaluation evaluation = evaluateBag(bag_path, truth_path, score);
    if (kept)
      *kept = evaluation;
    return evaluation.cloud.rms;
  };
  core::TimingConfig true_timing;
  true_timing.time_offset = run.true_offset;
  true_timing.beam_order = run.true_reversed ? core::BeamOrder::kReversed : core::BeamOrder::kAsMessage;
  true_timing.scan_period = truth.sweep_period;
  true_timing.use_scan_period = true;
  Evaluation with_truth;
  run.true_timing_mm = cloudRms(true_timing, &with_truth);
  run.floor_mm = with_truth.noise_only_rms;
  run.raw_mm = with_truth.raw.rms;
  if (estimate.told) {
    Evaluation with_estimate;
    run.corrected_mm = cloudRms(estimate.timing, &with_estimate);
    run.scan_mm = with_estimate.scan.rms;
  } else {
    run.corrected_mm = run.scan_mm = std::numeric_limits<double>::quiet_NaN();
  }
  try {
    run.message_timing_mm = cloudRms(core::TimingConfig(), nullptr);
  } catch (const std::exception&) {
    run.message_timing_mm = -1.0;  // the node refuses such scans (no period, or an absurd sweep)
  }
  std::remove(bag_path.c_str());
  std::remove(truth_path.c_str());
  return run;
}

std::string calibrationTableHeader() {
  return "| scenario | fault | true offset [ms] | estimated [ms] | error [ms] | order | period [ms] | "
         "written | message's timing | estimated timing | true timing | noise floor | ours / floor |\n"
         "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
}

std::string calibrationTableRow(const CalibrationRun& run) {
  const core::TimingEstimate& estimate = run.calibration.estimate;
  const core::TimingConfig& timing = estimate.timing;
  std::string written;
  if (!estimate.told) {
    written = "nothing (too little turning)";
  } else if (!estimate.changed) {
    written = "unchanged";
  } else {
    char text[160];
    std::snprintf(text, sizeof text, "%s%s%s", timing.stamp_at == core::StampAt::kEnd ? "stamp_at end " : "",
                  timing.beam_order == core::BeamOrder::kReversed ? "reversed " : "",
                  estimate.period_estimated ? "scan_period " : "");
    written = text;
    if (timing.time_offset != 0.0) {
      std::snprintf(text, sizeof text, "time_offset %.2f ms", timing.time_offset * 1e3);
      written += text;
    }
  }
  char period[48];
  std::snprintf(period, sizeof period, "%.3f%s", estimate.period * 1e3,
                estimate.period_estimated ? " (stamps)" : "");
  char message[32];
  if (run.message_timing_mm < 0.0)
    std::snprintf(message, sizeof message, "refused");
  else
    std::snprintf(message, sizeof message, "%.1f", run.message_timing_mm);
  char row[1024];
  std::snprintf(
      row, sizeof row,
      "| %s | %s | %.2f | %.2f ± %.2f | %+.2f | %s (%.0f %%) | %s | %s | %s | %.2f | %.2f | %.2f | %.3f |\n",
      run.recording.scenario.c_str(), run.recording.fault.c_str(), run.true_offset * 1e3,
      estimate.time_offset * 1e3, estimate.offset_sigma * 1e3, run.offset_error * 1e3,
      run.order_right ? "right" : "WRONG", 100.0 * estimate.order_confidence, period, written.c_str(),
      message, run.corrected_mm, run.true_timing_mm, run.floor_mm, run.corrected_mm / run.floor_mm);
  return row;
}

}  // namespace lidar_deskew::eval
