// deskew_calibration_experiments [--only K]: the evidence table of docs/RESULTS_CALIBRATION.md (run by
// scripts/calibration_experiments.sh): every case of eval::calibrationCases() simulated, calibrated and
// scored. Prints markdown rows as they finish; exits 1 when a case misses a target (offset within
// 0.5 ms, the beam order right, the cloud within 5 % of the noise floor, the fault-free ones unchanged).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "lidar_deskew/eval/calibration_runs.h"

int main(int argc, char** argv) {
  using namespace lidar_deskew;
  int only = -1;
  std::string directory = "/tmp";
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--only" && a + 1 < argc) {
      only = std::atoi(argv[++a]);
    } else if (arg == "--directory" && a + 1 < argc) {
      directory = argv[++a];
    } else {
      std::fprintf(stderr, "usage: %s [--only K] [--directory DIR]\n", argv[0]);
      return 2;
    }
  }
  std::printf("%s", eval::calibrationTableHeader().c_str());
  std::fflush(stdout);
  int missed = 0;
  const auto cases = eval::calibrationCases();
  for (std::size_t k = 0; k < cases.size(); ++k) {
    if (only >= 0 && static_cast<std::size_t>(only) != k)
      continue;
    try {
      const eval::CalibrationRun run = eval::runCalibrationCase(cases[k], directory);
      std::printf("%s", eval::calibrationTableRow(run).c_str());
      const bool fault_free = !cases[k].timing_fault.any();
      const bool met = run.calibration.estimate.told && std::abs(run.offset_error) <= 0.0005 &&
                       run.order_right && run.corrected_mm <= 1.05 * run.floor_mm &&
                       (!fault_free || !run.calibration.estimate.changed);
      if (!met) {
        ++missed;
        std::fprintf(stderr, "case %zu (%s, %s) misses a target%s\n", k, cases[k].scenario.c_str(),
                     cases[k].fault.c_str(),
                     run.calibration.estimate.told ? "" : (": " + run.calibration.estimate.why).c_str());
      }
    } catch (const std::exception& error) {
      ++missed;
      std::fprintf(stderr, "case %zu: %s\n", k, error.what());
    }
    std::fflush(stdout);
  }
  return missed ? 1 : 0;
}
