// deskew_simulate: writes a simulated recording of one of the paper's experiments as a ROS 1 bag, with
// its ground-truth file.
//
//   deskew_simulate --list
//   deskew_simulate --scenario UTM-30LX/high/arc --bag out.bag --truth out.truth [--noise] [--seed N]
//                   [--tf-rate HZ] [--clockwise] [--duration S]
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "lidar_deskew/sim/sim_bag.h"

namespace {

int usage(const char* program) {
  std::fprintf(
      stderr,
      "usage: %s --list\n"
      "       %s --scenario NAME --bag OUT.bag --truth OUT.truth [--noise] [--seed N] [--tf-rate HZ]\n"
      "          [--clockwise]\n",
      program, program);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lidar_deskew;
  std::string scenario_name, bag_path, truth_path;
  bool clockwise = false;
  double duration = 0.0;
  sim::SimBagOptions options;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "--list") {
      for (const sim::Scenario& scenario : sim::paperScenarios())
        std::printf("%s\n", scenario.name.c_str());
      return 0;
    } else if (arg == "--scenario" && has_value) {
      scenario_name = argv[++a];
    } else if (arg == "--bag" && has_value) {
      bag_path = argv[++a];
    } else if (arg == "--truth" && has_value) {
      truth_path = argv[++a];
    } else if (arg == "--duration" && has_value) {
      duration = std::atof(argv[++a]);
    } else if (arg == "--clockwise") {
      clockwise = true;
    } else if (arg == "--noise") {
      options.noise = true;
    } else if (arg == "--seed" && has_value) {
      options.seed = static_cast<unsigned>(std::strtoul(argv[++a], nullptr, 10));
    } else if (arg == "--tf-rate" && has_value) {
      options.tf_rate = std::atof(argv[++a]);
    } else {
      return usage(argv[0]);
    }
  }
  if (scenario_name.empty() || bag_path.empty() || truth_path.empty())
    return usage(argv[0]);
  if (!(options.tf_rate > 0.0)) {
    std::fprintf(stderr, "--tf-rate must be > 0 Hz\n");
    return 2;
  }
  try {
    sim::Scenario scenario = sim::findScenario(scenario_name);
    if (clockwise) {
      scenario = sim::clockwiseVariant(scenario);
    }
    if (duration > 0.0) {  // longer recordings (benchmarks); the last motion piece goes on
      scenario.duration = duration;
    }
    sim::writeSimulationBag(scenario, options, bag_path, truth_path);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "deskew_simulate: %s\n", error.what());
    return 1;
  }
  return 0;
}
