// deskew_metrics: scores a simulated bag against its truth file: distance of points to the true walls
// for the raw scans, our correction (cloud and re-binned scan) and laser_geometry's fixed-frame
// transformLaserScanToPointCloud.
//
//   deskew_metrics BAG TRUTH [--markdown] [--knot-interval S] [--rebin-gap-factor F] [--rebin-min-gap M]
//                  [--params FILE.yaml] [--figure-csv FILE] [--figure-scan K]
//   deskew_metrics --cloud BAG TRUTH [--markdown] [--params FILE.yaml]   (a multi-line bag of
//                  deskew_simulate --cloud-scenario: raw, constant velocity between two poses, ours, one
//                  motion query per point (exact: true), the noise floor (corrected with the true
//                  trajectory) and ours / floor as a ratio of RMS; --params: the node's parameters, e.g.
//                  interpolation)
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidar_deskew/eval/cloud_evaluate.h"
#include "lidar_deskew/eval/evaluate.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace {

int usage(const char* program) {
  std::fprintf(
      stderr,
      "usage: %s BAG TRUTH [--markdown] [--knot-interval S] [--rebin-gap-factor F] [--rebin-min-gap M]\n"
      "          [--params FILE.yaml (the timing and interpolation parameters)] [--figure-csv FILE] "
      "[--figure-scan K]\n"
      "       %s --cloud BAG TRUTH [--markdown] [--params FILE.yaml]\n",
      program, program);
  return 2;
}

std::string triple(const lidar_deskew::eval::ErrorStats& stats) {
  char text[64];
  std::snprintf(text, sizeof text, "%.2f / %.2f / %.2f", stats.rms, stats.p95, stats.max);
  return text;
}

/// Our RMS over the noise floor's, "–" with noise off: the floor is then only float32 rounding of the
/// coordinates (well under a micrometre), and a ratio to it says nothing.
std::string oursOverFloor(const lidar_deskew::eval::CloudEvaluation& result) {
  if (!(result.range_sigma_mm > 0.0) || !(result.truth_corrected.rms > 0.0))
    return "–";
  char text[32];
  std::snprintf(text, sizeof text, "%.3f", result.ours.rms / result.truth_corrected.rms);
  return text;
}

/// --cloud: a multi-line bag against its truth.
int cloudMetrics(const std::string& bag_path, const std::string& truth_path, bool markdown,
                 const lidar_deskew::ros_adapter::DeskewParams& params) {
  using namespace lidar_deskew;
  const eval::CloudEvaluation result = eval::evaluateCloudBag(bag_path, truth_path, "/points", params);
  if (markdown) {
    std::printf("| %s | %s | %zu | %.0f | %s | %s | %s | %s | %s | %s |\n", result.scenario.c_str(),
                result.convention.c_str(), result.clouds, result.range_sigma_mm, triple(result.raw).c_str(),
                triple(result.two_pose).c_str(), triple(result.ours).c_str(),
                triple(result.per_point).c_str(), triple(result.truth_corrected).c_str(),
                oursOverFloor(result).c_str());
  } else {
    std::printf("scenario        %s, %s (%zu clouds, range noise %.0f mm)\n", result.scenario.c_str(),
                result.convention.c_str(), result.clouds, result.range_sigma_mm);
    std::printf("distance to the true surfaces [mm]  RMS / p95 / max\n");
    std::printf("  raw                   %s  (%zu points)\n", triple(result.raw).c_str(), result.raw.count);
    std::printf("  two poses, constant v %s\n", triple(result.two_pose).c_str());
    std::printf("  ours                  %s\n", triple(result.ours).c_str());
    std::printf("  one lookup per point  %s\n", triple(result.per_point).c_str());
    std::printf("  truth-corrected       %s  (the noise floor: the true trajectory)\n",
                triple(result.truth_corrected).c_str());
    std::printf("ours / floor (RMS)      %s\n", oursOverFloor(result).c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lidar_deskew;
  std::string bag_path, truth_path;
  bool markdown = false;
  eval::EvaluateOptions options;
  bool cloud = false;
  std::string params_file;  // the scans' timing, as the node and deskew_bag read it (deskew_calibrate's)
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "--markdown") {
      markdown = true;
    } else if (arg == "--cloud") {
      cloud = true;
    } else if (arg == "--knot-interval" && has_value) {
      options.deskew.knot_interval = std::atof(argv[++a]);
    } else if (arg == "--rebin-gap-factor" && has_value) {
      options.rebin.gap_factor = std::atof(argv[++a]);
    } else if (arg == "--rebin-min-gap" && has_value) {
      options.rebin.min_gap = std::atof(argv[++a]);
    } else if (arg == "--figure-csv" && has_value) {
      options.figure_csv = argv[++a];
    } else if (arg == "--params" && has_value) {
      params_file = argv[++a];
    } else if (arg == "--figure-scan" && has_value) {
      options.figure_scan = static_cast<std::size_t>(std::strtoul(argv[++a], nullptr, 10));
    } else if (!arg.empty() && arg[0] != '-' && bag_path.empty()) {
      bag_path = arg;
    } else if (!arg.empty() && arg[0] != '-' && truth_path.empty()) {
      truth_path = arg;
    } else {
      return usage(argv[0]);
    }
  }
  if (bag_path.empty() || truth_path.empty())
    return usage(argv[0]);
  try {
    // Offline, as deskew_bag: the twist fit reads all it can after the sweep unless told otherwise.
    ros_adapter::DeskewParams params;
    params.deskew.fit_look_ahead = core::kFitHorizon;
    options.deskew.fit_look_ahead = core::kFitHorizon;
    if (!params_file.empty()) {
      const std::map<std::string, std::string> values = ros_adapter::readParamFile(params_file);
      std::vector<std::string> names;
      for (const auto& entry : values)
        names.push_back(entry.first);
      for (const std::string& unknown : ros_adapter::DeskewParams::unknownNames(names))
        throw std::runtime_error(params_file + ": unknown parameter " + unknown);
      std::map<std::string, std::string> with_default = values;
      with_default.emplace("fit_look_ahead", std::to_string(core::kFitHorizon));
      params = ros_adapter::DeskewParams::load(ros_adapter::TextParams(with_default));
      options.timing = params.timing;
      options.deskew.interpolation = params.deskew.interpolation;
      options.deskew.fit_look_ahead = params.deskew.fit_look_ahead;
    }
    if (cloud)
      return cloudMetrics(bag_path, truth_path, markdown, params);
    const eval::Evaluation result = eval::evaluateBag(bag_path, truth_path, options);
    if (markdown) {
      std::printf("| %s | %zu | %.0f | %s | %s | %s | %s |\n", result.scenario.c_str(), result.scans,
                  result.range_sigma_mm, triple(result.raw).c_str(), triple(result.cloud).c_str(),
                  triple(result.scan).c_str(), triple(result.laser_geometry).c_str());
    } else {
      std::printf("scenario        %s (%zu scans, range noise %.0f mm)\n", result.scenario.c_str(),
                  result.scans, result.range_sigma_mm);
      if (result.left_out > 0)
        std::printf("left out        %zu scans tf does not cover\n", result.left_out);
      std::printf("distance to the true walls [mm]  RMS / p95 / max\n");
      std::printf("  raw            %s  (%zu points)\n", triple(result.raw).c_str(), result.raw.count);
      std::printf("  corrected      %s  (%zu points)\n", triple(result.cloud).c_str(), result.cloud.count);
      std::printf(
          "  corrected scan %s  (%zu filled bins, %zu = %.2f %% farther than 10 mm; of the %zu the "
          "truth-corrected scan fills, %zu = %.2f %% empty)\n",
          triple(result.scan).c_str(), result.scan.count, result.scan_over_1cm,
          result.scan.count ? 100.0 * result.scan_over_1cm / result.scan.count : 0.0,
          result.truth_scan_filled, result.scan_emptied,
          result.truth_scan_filled ? 100.0 * result.scan_emptied / result.truth_scan_filled : 0.0);
      std::printf("  laser_geometry %s  (%zu points)\n", triple(result.laser_geometry).c_str(),
                  result.laser_geometry.count);
      std::printf(
          "corrected to its beam's true hit [mm]  %s; range noise alone gives %.2f mm RMS to the walls\n",
          triple(result.cloud_to_hit).c_str(), result.noise_only_rms);
    }
  } catch (const std::exception& error) {
    std::fprintf(stderr, "deskew_metrics: %s\n", error.what());
    return 1;
  }
  return 0;
}
