// The shape measure of a recording (eval::measureShapes, deskew_bag --consistency) on simulated bags
// with known timing faults and odometry: the simulator's truth says which correction is right and
// how far tf's rotation is off (docs/CALIBRATION.md, "Shapes"). No roscore.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <memory>
#include <string>

#include "lidar_deskew/eval/shape_consistency.h"
#include "lidar_deskew/sim/sim_bag.h"
#include "support/temporary.h"

namespace lidar_deskew::eval {
namespace {

std::string temporary(const std::string& name) { return test::temporary("shape_consistency", name); }

/// The LDS-01 turns drive (5 Hz, 360 beams, σ 15 mm; turn rate changing every 1-2 s) with range noise.
struct SimulatedBag {
  std::string bag = temporary("turns.bag"), truth = temporary("turns.truth");
  explicit SimulatedBag(const sim::SimBagOptions& options) {
    sim::writeSimulationBag(sim::findScenario("LDS-01/normal/turns"), options, bag, truth);
  }
  ~SimulatedBag() {
    std::remove(bag.c_str());
    std::remove(truth.c_str());
  }
};

sim::SimBagOptions withNoise() {
  sim::SimBagOptions options;
  options.noise = true;
  return options;
}

TEST(ShapeConsistency, RightTimingSharpensShapesAndTfFits) {
  const SimulatedBag recording(withNoise());
  const ShapeReport report = measureShapes(recording.bag, "/scan", ros_adapter::DeskewParams());
  std::printf("right timing: %s; rotation %s\n", formatShapes(report.shapes).c_str(),
              formatRotation(report.rotation).c_str());
  ASSERT_GE(report.shapes.pairs, 50u);
  EXPECT_LT(report.shapes.ratio, 0.6);
  EXPECT_NEAR(report.rotation.scale, 1.0, 0.03);
  EXPECT_GT(report.rotation.correlation, 0.99);
  EXPECT_GE(report.rotation.turning_pairs, 30u);
  EXPECT_TRUE(report.warnings.empty());
}

TEST(ShapeConsistency, WrongBeamOrderMakesShapesWorseAndIsSaid) {
  sim::SimBagOptions options = withNoise();
  options.timing_fault.reversed = true;
  const SimulatedBag recording(options);
  ros_adapter::DeskewParams params;  // the message's timing: wrong
  const ShapeReport wrong = measureShapes(recording.bag, "/scan", params);
  std::printf("beams reversed, message's timing: %s\n", formatShapes(wrong.shapes).c_str());
  ASSERT_GE(wrong.shapes.pairs, 50u);
  EXPECT_GT(wrong.shapes.ratio, 1.2);
  ASSERT_EQ(wrong.warnings.size(), 1u);
  EXPECT_EQ(wrong.warnings[0].find("correction makes shapes worse than raw"), 0u) << wrong.warnings[0];
  params.timing.beam_order = core::BeamOrder::kReversed;  // the truth's
  const ShapeReport right = measureShapes(recording.bag, "/scan", params);
  EXPECT_LT(right.shapes.ratio, 0.6);
  EXPECT_TRUE(right.warnings.empty());
}

/// Runs deskew_bag with `args`; returns what it printed (stdout and stderr).
std::string runTool(const std::string& args) {
  std::string printed;
  const std::string command = std::string(LIDAR_DESKEW_BAG_TOOL) + " " + args + " 2>&1";
  const std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  std::array<char, 4096> buffer;
  while (pipe && fgets(buffer.data(), buffer.size(), pipe.get()))
    printed += buffer.data();
  return printed;
}

TEST(ShapeConsistency, OdometryThatTurnsTooMuchIsSeenAndDeskewBagWarns) {
  // The odometry reports 2.5x the true rotation: scan matching sees 0.4x tf's.
  sim::SimBagOptions options = withNoise();
  options.odom_yaw_scale = 2.5;
  const SimulatedBag recording(options);
  const ShapeReport report = measureShapes(recording.bag, "/scan", ros_adapter::DeskewParams());
  std::printf("odometry 2.5x: %s; rotation %s\n", formatShapes(report.shapes).c_str(),
              formatRotation(report.rotation).c_str());
  EXPECT_NEAR(report.rotation.scale, 0.4, 0.03);
  EXPECT_GT(report.rotation.correlation, 0.99);
  EXPECT_GT(report.shapes.ratio, 1.0);  // corrected with 2.5x the turn, shapes are worse than raw

  const std::string output = temporary("out.bag");
  const std::string printed = runTool(recording.bag + " " + output + " --quiet --consistency");
  std::remove(output.c_str());
  char figure[80];
  std::snprintf(figure, sizeof figure, "scan matching sees %.2fx tf's rotation", report.rotation.scale);
  EXPECT_NE(printed.find("warning: /scan: tf's rotation does not fit the scans: " + std::string(figure)),
            std::string::npos)
      << printed;
  EXPECT_NE(printed.find("warning: /scan: correction makes shapes worse than raw"), std::string::npos)
      << printed;
  EXPECT_NE(printed.find("/scan shapes (scans up to 1.5 s apart"), std::string::npos) << printed;
}

}  // namespace
}  // namespace lidar_deskew::eval
