// The noise floor of the multi-line scenarios (eval::evaluateCloudBag, as deskew_metrics --cloud and
// docs/RESULTS_CLOUDS.md): the recorded clouds corrected with the TRUE trajectory (the truth file's
// motion, plain Eigen: no tf, no MRPT), scored against the true surfaces like every other column.
// Recordings as scripts/cloud_experiments.sh makes them (1 s, 10 sweeps, tf at 50 Hz, seed 1), so the
// printed numbers are the table's. Tolerances in mm.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "lidar_deskew/eval/cloud_evaluate.h"
#include "lidar_deskew/sim/cloud_bag.h"
#include "lidar_deskew/sim/cloud_scenario.h"
#include "support/temporary.h"

namespace lidar_deskew::eval {
namespace {

/// The OS1-64 in Ouster's layout, the VLP-16 in Velodyne's stamped at the last packet (as the script).
CloudEvaluation simulateAndEvaluate(const std::string& scenario, bool noise) {
  std::string stem = test::temporary("cloud_floor", "");
  for (char c : scenario)
    stem += (c == '/' ? '_' : c);
  const std::string bag = stem + ".bag", truth = stem + ".truth";
  sim::CloudBagOptions options;
  options.convention =
      scenario.rfind("OS1-64/", 0) == 0 ? sim::CloudConvention::kOuster : sim::CloudConvention::kVelodyneLast;
  options.noise = noise;
  sim::writeCloudBag(sim::findCloudScenario(scenario), options, bag, truth);
  const CloudEvaluation result = evaluateCloudBag(bag, truth, "/points", ros_adapter::DeskewParams());
  std::remove(bag.c_str());
  std::remove(truth.c_str());
  std::printf(
      "%-24s noise %-3s: raw %.2f, ours %.4f, one lookup per point %.4f, floor %.4f mm RMS (max %.4f)",
      scenario.c_str(), noise ? "on" : "off", result.raw.rms, result.ours.rms, result.per_point.rms,
      result.truth_corrected.rms, result.truth_corrected.max);
  if (noise)
    std::printf(", ours / floor %.5f", result.ours.rms / result.truth_corrected.rms);
  std::printf("\n");
  return result;
}

// Noise off, the floor is the truth itself: the recorded points moved with the true motion lie on the
// true surfaces up to the float32 coordinates and time fields (< 0.05 mm everywhere). Ours follows the
// twist between tf's 50 Hz samples: on the arc that is the arc (what is left is the 5 ms knots' chord,
// 0.04 mm RMS); on rough ground (z, pitch and roll oscillating at 1.7-3 Hz) the twist changes within each
// sample interval, which tf's samples do not show (0.5 mm RMS, as tf's own straight line).
TEST(CloudFloor, NoiseOffTheFloorIsTheTruth) {
  for (const char* scenario : {"VLP16/high/arc", "OS1-64/rough/arc"}) {
    const CloudEvaluation result = simulateAndEvaluate(scenario, false);
    EXPECT_EQ(result.range_sigma_mm, 0.0) << scenario;
    EXPECT_EQ(result.truth_corrected.count, result.raw.count) << scenario;  // every return, once
    EXPECT_EQ(result.truth_corrected.count, result.ours.count) << scenario;
    EXPECT_LT(result.truth_corrected.rms, 0.05) << scenario;
    EXPECT_LT(result.truth_corrected.max, 0.05) << scenario;
    EXPECT_LT(result.ours.rms, std::string(scenario) == "VLP16/high/arc" ? 0.1 : 1.0) << scenario;
    EXPECT_GT(result.ours.rms, result.truth_corrected.rms) << scenario;  // the floor is below: it is truth
    EXPECT_GT(result.raw.rms, 100.0) << scenario;
  }
}

// Noise on (σ 30 mm along the beams): the floor is the scenario's own, not the standing robot's. Each
// point's distance to the surface it hit is at most its noise, so the floor is below σ; it is above ours
// by nothing the correction could remove, and near (≥ 0.9 ×) the standing robot's. Ours ≤ 1.02 × the
// floor on rough ground and the high-speed arc, for both sensors (measured ≤ 1.001: the target).
TEST(CloudFloor, NoiseOnOursIsAtTheFloor) {
  for (const char* sensor : {"VLP16", "OS1-64"}) {
    const CloudEvaluation standing = simulateAndEvaluate(std::string(sensor) + "/static/still", true);
    // Standing, there is no motion to correct: every column is the floor itself.
    EXPECT_NEAR(standing.ours.rms, standing.truth_corrected.rms, 1e-6) << sensor;
    EXPECT_NEAR(standing.raw.rms, standing.truth_corrected.rms, 1e-6) << sensor;
    for (const char* motion : {"/rough/arc", "/high/arc"}) {
      const std::string scenario = std::string(sensor) + motion;
      const CloudEvaluation result = simulateAndEvaluate(scenario, true);
      const sim::ErrorStats& floor = result.truth_corrected;
      EXPECT_EQ(result.range_sigma_mm, 30.0) << scenario;
      EXPECT_EQ(floor.count, result.ours.count) << scenario;
      EXPECT_LT(floor.rms, result.range_sigma_mm) << scenario;
      // Where the motion is followed exactly (the arc) ours and the floor agree to 1 um either way.
      EXPECT_LE(floor.rms, result.ours.rms + 1e-3) << scenario;
      EXPECT_LE(floor.rms, result.per_point.rms + 1e-3) << scenario;
      EXPECT_GE(floor.rms, 0.9 * standing.truth_corrected.rms) << scenario;
      EXPECT_LE(result.ours.rms, 1.02 * floor.rms) << scenario;
      // The two-pose correction is measurably above the floor on both (its chord, 13-15 mm noise off).
      EXPECT_GT(result.two_pose.rms, 1.1 * floor.rms) << scenario;
    }
  }
}

}  // namespace
}  // namespace lidar_deskew::eval
