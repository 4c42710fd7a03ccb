#include "lidar_deskew/eval/calibration_runs.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include <unistd.h>

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
      // Latencies beyond the first window of old (1.25 sweeps): 1.65 sweeps at 5 Hz, 3.4 at 40 Hz,
      // stamped at the end plus 150 ms at 8 Hz (2.2 sweeps).
      {lds, "stamp 330 ms late (1.65 sweeps)", fault(0.330), 25},
      {utm_high, "stamp 85 ms late (3.4 sweeps)", fault(0.085), 26},
      {ild, "stamped at the end + 150 ms late", fault(atEnd(ild) + 0.150), 27},
      // Steady drives: one constant twist. The offset cannot show; the order and the period do.
      {"LDS-01/normal/circle", "reversed", fault(0.0, true), 28},
      {"ILD26TRI/normal/spin", "time_increment and scan_time 0", fault(0.0, false, 0.0, true), 29},
      {"LDS-01/normal/spin", "time_increment x 0.5, reversed", fault(0.0, true, 0.5), 30},
      {"UTM-30LX/normal/circle", "time_increment x 1000 (ms as s)", fault(0.0, false, 1000.0), 31},
      {"ILD26TRI/normal/circle", "reversed, stamp 100 ms late (not observable)", fault(0.100, true), 32},
  };
}

bool offsetObservable(const CalibrationCase& recording) {
  return sim::findScenario(recording.scenario).motion == "turns";
}

std::vector<CalibrationCase> coverageCases(std::size_t count, unsigned seed) {
  const char* sensors[] = {"LDS-01", "ILD26TRI", "UTM-30LX", "UTM-30LX-270"};
  const double tf_rates[] = {50.0, 20.0, 10.0};
  const double odom_noises[] = {0.0, 0.02, 0.05};
  std::mt19937 random(seed);
  std::vector<CalibrationCase> cases;
  for (std::size_t k = 0; k < count; ++k) {
    CalibrationCase recording;
    recording.scenario =
        std::string(sensors[random() % 4]) + (random() % 2 ? "/high/turns" : "/normal/turns");
    const double period = 1.0 / sim::findScenario(recording.scenario).lidar.rate;
    const double stamp_error =
        std::round(std::uniform_real_distribution<double>(-0.5, 3.0)(random) * period * 1e4) / 1e4;
    const bool reversed = random() % 2;
    recording.timing_fault = fault(stamp_error, reversed);
    recording.tf_rate = tf_rates[random() % 3];
    recording.odom_noise = odom_noises[random() % 3];
    recording.seed = 1000 + static_cast<unsigned>(k);
    recording.odom_seed = 2000 + static_cast<unsigned>(k);
    char name[160];
    std::snprintf(name, sizeof name, "stamp %.1f ms late%s, odometry %.0f Hz%s", stamp_error * 1e3,
                  reversed ? ", reversed" : "", recording.tf_rate,
                  recording.odom_noise > 0.0
                      ? (", noise " + std::to_string(recording.odom_noise).substr(0, 4)).c_str()
                      : "");
    recording.fault = name;
    cases.push_back(recording);
  }
  return cases;
}

CalibrationRun runCalibrationCase(const CalibrationCase& recording, const std::string& directory,
                                  bool score_it, const core::TimingFitConfig& fit) {
  // The process id in the name: test shards and experiment runs side by side never share a file.
  const std::string stem =
      directory + "/calibration_" + std::to_string(::getpid()) + "_" + std::to_string(recording.seed);
  const std::string bag_path = stem + ".bag", truth_path = stem + ".truth";
  sim::SimBagOptions options;
  options.noise = true;
  options.seed = recording.seed;
  options.timing_fault = recording.timing_fault;
  options.tf_rate = recording.tf_rate;
  options.odom_noise = recording.odom_noise;
  options.odom_noise_seed = recording.odom_seed;
  const sim::Scenario scenario = sim::findScenario(recording.scenario);
  sim::writeSimulationBag(scenario, options, bag_path, truth_path);
  const sim::Truth truth = sim::readTruth(truth_path);

  CalibrationRun run;
  run.recording = recording;
  bag::CalibrateOptions calibrate;
  calibrate.input = bag_path;
  calibrate.scan_topic = "/scan";
  calibrate.fit = fit;
  run.calibration = bag::calibrateBag(calibrate);
  run.true_offset = truth.timeOffset();
  run.true_reversed = truth.timing_fault.reversed;
  const core::TimingEstimate& estimate = run.calibration.estimate;
  run.offset_error = estimate.time_offset - run.true_offset;
  run.order_right = (estimate.timing.beam_order == core::BeamOrder::kReversed) == run.true_reversed;
  if (!score_it) {
    std::remove(bag_path.c_str());
    std::remove(truth_path.c_str());
    return run;
  }

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
    written = "nothing (" + core::toString(estimate.cause) + ")";
  } else if (!estimate.changed) {
    written = estimate.offset_told ? "unchanged"
                                   : "unchanged; offset not told (" + core::toString(estimate.cause) + ")";
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
    if (!estimate.offset_told)
      written += "; offset not told (" + core::toString(estimate.cause) + ")";
  }
  char period[48];
  std::snprintf(period, sizeof period, "%.3f%s", estimate.period * 1e3,
                estimate.period_estimated ? " (stamps)" : "");
  char message[32];
  if (run.message_timing_mm < 0.0)
    std::snprintf(message, sizeof message, "refused");
  else
    std::snprintf(message, sizeof message, "%.1f", run.message_timing_mm);
  char offset[64], error[32];
  if (estimate.offset_told) {
    std::snprintf(offset, sizeof offset, "%.2f ± %.2f", estimate.time_offset * 1e3,
                  estimate.offset_sigma * 1e3);
    std::snprintf(error, sizeof error, "%+.2f", run.offset_error * 1e3);
  } else {
    std::snprintf(offset, sizeof offset, "not told");
    std::snprintf(error, sizeof error, "-");
  }
  char row[1024];
  std::snprintf(row, sizeof row,
                "| %s | %s | %.2f | %s | %s | %s (%.0f %%) | %s | %s | %s | %.2f | %.2f | %.2f | %.3f |\n",
                run.recording.scenario.c_str(), run.recording.fault.c_str(), run.true_offset * 1e3, offset,
                error, run.order_right ? "right" : "WRONG", 100.0 * estimate.order_confidence, period,
                written.c_str(), message, run.corrected_mm, run.true_timing_mm, run.floor_mm,
                run.corrected_mm / run.floor_mm);
  return row;
}

}  // namespace lidar_deskew::eval
