// The evidence for deskew_calibrate (docs/RESULTS_CALIBRATION.md): simulated recordings with timing
// faults injected into their LaserScans, calibrated, then corrected with the estimate and scored against
// the truth.
#pragma once

#include <string>
#include <vector>

#include "lidar_deskew/bag/bag_calibrate.h"
#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::eval {

/// One recording: a scenario and the fault in its scans.
struct CalibrationCase {
  std::string scenario;  ///< e.g. "LDS-01/normal/turns"
  std::string fault;     ///< as in the table, e.g. "stamped at the end, reversed"
  sim::TimingFault timing_fault;
  unsigned seed = 1;        ///< of the range noise (always on)
  double tf_rate = 50.0;    ///< [Hz] of the odometry on /tf
  double odom_noise = 0.0;  ///< sim::SimBagOptions::odom_noise (0: perfect odometry)
  unsigned odom_seed = 1;   ///< of the odometry noise
};

/// The recordings of docs/RESULTS_CALIBRATION.md: every fault the issue names (stamp at the end;
/// offsets of +-10-60 ms; reversed order; both; time_increment and scan_time 0; time_increment off by a
/// factor), on LDS-01, ILD26TRI, UTM-30LX and UTM-30LX-270 driving turns at normal and high speed, and
/// two without a fault (the first 24); latencies of 1.3 to 3.4 sweeps (3); and steady drives (one
/// constant twist), where the offset cannot show but the beam order and the period do (5).
std::vector<CalibrationCase> calibrationCases();

/// Whether a case's offset can show: its scans turn at different rates (not a steady drive).
bool offsetObservable(const CalibrationCase& recording);

/// `count` recordings for the coverage of the offset's uncertainty: drawn from `seed` over the turns
/// drives of every sensor at both speeds, offsets from -3 sweeps to +0.5 sweep, either beam order,
/// odometry at 50, 20 or 10 Hz, perfect or noisy (0.02, 0.05 per step), the range noise's seed.
std::vector<CalibrationCase> coverageCases(std::size_t count, unsigned seed);

struct CalibrationRun {
  CalibrationCase recording;
  bag::Calibration calibration;
  double true_offset = 0.0;  ///< [s] first beam - stamp, the truth
  bool true_reversed = false;
  double offset_error = 0.0;  ///< [s] estimate - truth
  bool order_right = false;
  double floor_mm = 0.0;          ///< what range noise alone gives (the noise floor) [mm RMS]
  double corrected_mm = 0.0;      ///< our cloud with the estimated timing [mm RMS to the true walls]
  double scan_mm = 0.0;           ///< our LaserScan with it
  double true_timing_mm = 0.0;    ///< our cloud with the true timing
  double message_timing_mm = -1;  ///< our cloud with the message's timing (-1: the node refuses it)
  double raw_mm = 0.0;
};

/// Simulates the case into `directory` (bag and truth), calibrates it (under `fit`) and, with `score`,
/// scores the corrections against the truth. Throws std::runtime_error on failure.
CalibrationRun runCalibrationCase(const CalibrationCase& recording, const std::string& directory,
                                  bool score = true,
                                  const core::TimingFitConfig& fit = core::TimingFitConfig());

/// One markdown table row of a run (see calibrationTableHeader()).
std::string calibrationTableRow(const CalibrationRun& run);
std::string calibrationTableHeader();

}  // namespace lidar_deskew::eval
