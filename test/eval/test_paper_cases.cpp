// The paper's experiments on real bag files, through a real tf2 buffer and laser_geometry, scored
// against the simulator's truth. Tolerances in mm.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "lidar_deskew/eval/evaluate.h"
#include "lidar_deskew/sim/sim_bag.h"
#include "support/odometry_classes.h"
#include "support/temporary.h"

namespace lidar_deskew::eval {
namespace {

using test::odometryTiming;

Evaluation simulateAndEvaluate(const std::string& scenario, bool noise, double tf_rate = 50.0,
                               bool clockwise = false,
                               core::Interpolation interpolation = core::Interpolation::kTwist) {
  std::string stem = test::temporary("paper_case", "");
  for (char c : scenario)
    stem += (c == '/' ? '_' : c);
  const std::string bag = stem + ".bag", truth = stem + ".truth";
  sim::SimBagOptions options;
  options.noise = noise;
  options.tf_rate = tf_rate;
  const sim::Scenario found = sim::findScenario(scenario);
  sim::writeSimulationBag(clockwise ? sim::clockwiseVariant(found) : found, options, bag, truth);
  EvaluateOptions evaluate_options;
  evaluate_options.deskew.interpolation = interpolation;
  const Evaluation result = evaluateBag(bag, truth, evaluate_options);
  std::remove(bag.c_str());
  std::remove(truth.c_str());
  std::printf(
      "%-26s noise %-3s tf %3.0f Hz: raw %.2f, corrected %.3f, scan %.3f, laser_geometry %.2f mm RMS\n",
      scenario.c_str(), noise ? "on" : "off", tf_rate, result.raw.rms, result.cloud.rms, result.scan.rms,
      result.laser_geometry.rms);
  return result;
}

// Odometry as robots produce it: every planar scenario of the paper's suite and the LDS-01's fast smooth
// drive, range noise on, at each odometry class below. The twist fit as deskew_bag runs it (a 1 s
// look-ahead) against tf's line (interpolation linear): over the class at most as bad, and worse by
// more than 0.5 % (where both follow the samples: arcs against chords) on at most one scenario, named.
// Not yet never: with everything at once (5-7 Hz: too few samples in the window to estimate the
// noise, so the samples are taken as exact), LDS-01/high/rotation 21.5 against 20.7.
void expectNeverWorseThanTfsLine(const char* name, double noise, const sim::OdometryTiming& timing,
                                 bool range_noise = true) {
  std::vector<sim::Scenario> scenarios = sim::paperScenarios();
  for (const sim::Scenario& smooth : sim::smoothScenarios()) {
    if (smooth.name == "LDS-01/high/smooth")
      scenarios.push_back(smooth);
  }
  double linear_sum = 0.0, fit_sum = 0.0;
  int worse = 0;
  for (std::size_t k = 0; k < scenarios.size(); ++k) {
    const std::string bag = test::temporary("paper_case_odometry", "bag");
    const std::string truth = bag + ".truth";
    sim::SimBagOptions options;
    options.noise = range_noise;
    options.seed = static_cast<unsigned>(k % 3 + 1);
    options.odom_noise = noise;
    options.odom_noise_seed = options.seed;
    options.odom_timing = timing;
    sim::writeSimulationBag(scenarios[k], options, bag, truth);
    EvaluateOptions linear, fitted;
    linear.deskew.interpolation = core::Interpolation::kLinear;
    fitted.deskew.fit_look_ahead = core::kFitHorizon;
    const Evaluation line = evaluateBag(bag, truth, linear), fit = evaluateBag(bag, truth, fitted);
    std::remove(bag.c_str());
    std::remove(truth.c_str());
    if (fit.cloud.rms > 1.005 * line.cloud.rms) {
      ++worse;
      std::printf("%-18s %s: twist %.2f, linear %.2f mm RMS: worse\n", name, scenarios[k].name.c_str(), fit.cloud.rms,
                  line.cloud.rms);
    }
    linear_sum += line.cloud.rms;
    fit_sum += fit.cloud.rms;
  }
  std::printf("%-18s %zu scenarios: linear %.2f, twist with a 1 s look-ahead %.2f mm RMS (sum)\n", name,
              scenarios.size(), linear_sum, fit_sum);
  EXPECT_LE(fit_sum, linear_sum) << name;
  EXPECT_LE(worse, 1) << name;
}

TEST(PaperCases, NoisyOdometryNeverWorseThanTfsLine) {  // 10 % per 20 ms step
  expectNeverWorseThanTfsLine("noise 10 %", 0.1, {});
}
TEST(PaperCases, JitteringStampsNeverWorseThanTfsLine) {  // stamps off by up to 5 ms
  expectNeverWorseThanTfsLine("stamps +-5 ms", 0.0, odometryTiming(0.005, 0.0, 0.0, 0.0));
}
TEST(PaperCases, IrregularOdometryNeverWorseThanTfsLine) {  // 5-11 Hz
  expectNeverWorseThanTfsLine("5-11 Hz", 0.0, odometryTiming(0.0, 5.0, 11.0, 0.0));
}
TEST(PaperCases, EncoderTicksNeverWorseThanTfsLine) {  // 1 mm ticks
  expectNeverWorseThanTfsLine("1 mm ticks", 0.0, odometryTiming(0.0, 0.0, 0.0, 0.001));
}
// Range noise off, the wheel base of RESULTS.md's table (0.235 m): where ILD26TRI/varying's quantised
// turn rate once passed for noise (515.74 mm against tf's line's 14.08 at seed 1).
TEST(PaperCases, EncoderTicksWithoutRangeNoiseNeverWorseThanTfsLine) {
  sim::OdometryTiming ticks = odometryTiming(0.0, 0.0, 0.0, 0.001);
  ticks.wheel_base = 0.235;
  expectNeverWorseThanTfsLine("1 mm ticks, exact ranges", 0.0, ticks, false);
}
TEST(PaperCases, EverythingAtOnceNeverWorseThanTfsLine) {  // 5-7 Hz, noise, jitter and ticks
  expectNeverWorseThanTfsLine("5-7 Hz, all", 0.1, odometryTiming(0.005, 5.0, 7.0, 0.001));
}

// Noise off: what is left is the correction's own error. tf at 50 Hz is linear between samples, which
// at normal speed leaves well under 0.1 mm. The re-binned scan is exact where rays fall between two
// points on one wall; at corners it follows the chord between neighbouring returns (up to decimetres
// at 25 m with 1 deg beams), so its p95 is asserted and its RMS only printed.
TEST(PaperCases, NormalSpeedNoiseOff) {
  for (const char* scenario :
       {"ILD26TRI/normal/arc", "UTM-30LX/normal/rotation", "ILD26TRI/normal/translation"}) {
    const Evaluation result = simulateAndEvaluate(scenario, false);
    EXPECT_GT(result.scans, 3u);
    EXPECT_LT(result.cloud.rms, 0.5) << scenario;
    EXPECT_GT(result.raw.rms, 10.0) << scenario;  // centimetres
    EXPECT_LT(result.scan.p95, 0.5) << scenario;
    EXPECT_GT(result.scan.count, result.cloud.count * 9 / 10) << scenario;
  }
  // laser_geometry interpolates between the sweep's first and last pose: exact for a pure translation
  // or a spin about the laser, off by the chord on an arc.
  const Evaluation arc = simulateAndEvaluate("UTM-30LX/normal/arc", false);
  EXPECT_GT(arc.laser_geometry.rms, 2.0 * arc.cloud.rms);
}

// At 6 m/s and 5 rad/s tf's own linear interpolation between 50 Hz samples is off the arc by up to
// v w h^2 / 8 = 1.5 mm; at 200 Hz by 0.09 mm. The correction follows tf either way.
TEST(PaperCases, HighSpeedArcFollowsTf) {
  const Evaluation at_200_hz = simulateAndEvaluate("ILD26TRI/high/arc", false, 200.0);
  EXPECT_LT(at_200_hz.cloud.rms, 0.5);
  EXPECT_GT(at_200_hz.raw.rms, 100.0);
  const Evaluation at_50_hz = simulateAndEvaluate("ILD26TRI/high/arc", false, 50.0);
  EXPECT_LT(at_50_hz.cloud.max, 1.6);
  EXPECT_GT(at_50_hz.laser_geometry.rms, 10.0 * at_50_hz.cloud.rms);
}

// The clockwise variant of the sensor (negative angle increment) through the same bag and tf path.
TEST(PaperCases, ClockwiseSensor) {
  const Evaluation result = simulateAndEvaluate("ILD26TRI/normal/arc", false, 50.0, true);
  EXPECT_EQ(result.scenario, "ILD26TRI/normal/arc/clockwise");
  EXPECT_LT(result.cloud.rms, 0.5);
  EXPECT_GT(result.raw.rms, 10.0);
  EXPECT_LT(result.scan.p95, 0.5);
}

// Speed and turn rate changing inside each scan: tf at 200 Hz keeps its own interpolation error (a h^2 / 8
// for the 50 m/s^2 ramps) at 0.16 mm. laser_geometry, which sees only the sweep's end poses, stays near
// the raw error.
TEST(PaperCases, VaryingMotionNoiseOff) {
  const Evaluation result = simulateAndEvaluate("ILD26TRI/varying/varying", false, 200.0);
  EXPECT_LT(result.cloud.rms, 0.5);
  EXPECT_GT(result.raw.rms, 20.0);
  EXPECT_GT(result.laser_geometry.rms, 20.0 * result.cloud.rms);
  // At 50 Hz the turn rate flips every other sample, the speed's ramp every fourth: from the samples up
  // to the sweep's end a flip cannot be told from a smooth extremum by its neighbours alone, and the
  // fit must not carry a step into a parabola's slope (it did: 20.8 mm, where tf's line has 1.3).
  const Evaluation twist = simulateAndEvaluate("ILD26TRI/varying/varying", false, 50.0);
  const Evaluation linear =
      simulateAndEvaluate("ILD26TRI/varying/varying", false, 50.0, false, core::Interpolation::kLinear);
  EXPECT_LT(twist.cloud.rms, 0.5 * linear.cloud.rms);
}

// Noise on: the corrected points are as far from their true hits as the range noise puts them
// (sigma), and as far from the walls as noise alone would (sigma * rms cos incidence).
// Speed and turn rate following cosines (the smooth drives): the twist changes between tf's samples.
// tf's line and a constant twist per interval are both second order; the fit is third order between
// the samples (issue 24: at most 1/5 of linear at 10 Hz, 0.2 mm at 50 Hz).
TEST(PaperCases, SmoothMotionBetweenSamples) {
  for (const double rate : {10.0, 50.0}) {
    const Evaluation twist = simulateAndEvaluate("LDS-01/high/smooth", false, rate);
    const Evaluation linear =
        simulateAndEvaluate("LDS-01/high/smooth", false, rate, false, core::Interpolation::kLinear);
    EXPECT_LT(twist.cloud.rms, 0.2 * linear.cloud.rms) << rate;
    EXPECT_GT(linear.cloud.rms, rate < 20.0 ? 10.0 : 0.5) << rate;  // 16.7 and 0.67 mm
  }
  EXPECT_LT(simulateAndEvaluate("LDS-01/high/smooth", false, 50.0).cloud.rms, 0.2);
}

TEST(PaperCases, NoiseOnLeavesOnlyTheSensorNoise) {
  for (const char* scenario : {"UTM-30LX/normal/arc", "ILD26TRI/normal/arc"}) {
    const Evaluation result = simulateAndEvaluate(scenario, true);
    EXPECT_NEAR(result.cloud_to_hit.rms, result.range_sigma_mm, 0.1 * result.range_sigma_mm) << scenario;
    EXPECT_NEAR(result.cloud.rms, result.noise_only_rms, 0.1 * result.noise_only_rms) << scenario;
    EXPECT_GT(result.raw.rms, 1.5 * result.cloud.rms) << scenario;
  }
}

}  // namespace
}  // namespace lidar_deskew::eval
