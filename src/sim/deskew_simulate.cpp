// deskew_simulate: writes a simulated recording as a ROS 1 bag, with its ground-truth file: one of the
// planar experiments (LaserScan: the paper's, or the "turns" drives for timing calibration, optionally
// with timing faults or as a 2D driver writes its scans), or a multi-line LIDAR sweep by sweep
// (PointCloud2 in a driver's layout).
//
//   deskew_simulate --list | --list-paper | --list-calibration | --list-smooth | --list-clouds |
//                   --list-cloud-smooth | --list-conventions | --list-drivers
//   deskew_simulate --driver rplidar --bag out.bag --truth out.truth [--scenario NAME] [--stamp-error S]
//                   [--noise] [--seed N] [--tf-rate HZ] [--tf-margin S] [--duration S] [--odom-noise R]
//   deskew_simulate --scenario UTM-30LX/high/arc --bag out.bag --truth out.truth [--noise] [--seed N]
//                   [--tf-rate HZ] [--tf-margin S] [--clockwise] [--duration S] [--stamp-error S |
//                   --stamp-at-end] [--reversed] [--time-increment-factor F] [--zero-scan-time]
//                   [--odom-noise R [--odom-seed N]] [--odom-yaw-scale F] [--odom-jitter S]
//                   [--odom-rate LO:HI] [--odom-ticks M:B] [--odom-delivery late:S|burst:N]...
//   deskew_simulate --cloud-scenario VLP16/rough/arc --convention velodyne_first --bag out.bag
//                   --truth out.truth [--noise] [--seed N] [--tf-rate HZ] [--tf-margin S] [--duration S]
//                   [--latency S]
//                   [--odom-noise R [--odom-seed N]] [--odom-yaw-scale F] [--odom-jitter S]...
//                   (the --odom-* options as for --scenario)
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "lidar_deskew/sim/cloud_bag.h"
#include "lidar_deskew/sim/drivers.h"
#include "lidar_deskew/sim/sim_bag.h"

namespace {

int usage(const char* program) {
  std::fprintf(
      stderr,
      "usage: %s --list | --list-paper | --list-calibration | --list-smooth | --list-clouds |\n"
      "          --list-cloud-smooth | --list-conventions | --list-drivers\n"
      "       %s --scenario NAME | --driver NAME [--scenario NAME] --bag OUT.bag --truth OUT.truth\n"
      "          [--noise] [--seed N] [--tf-rate HZ]\n"
      "          [--tf-margin S] [--clockwise] [--duration S] [--stamp-error S | --stamp-at-end]\n"
      "          [--reversed] [--time-increment-factor F] [--zero-scan-time]\n"
      "          [--odom-noise R [--odom-seed N]] [--odom-yaw-scale F] [--odom-jitter S]\n"
      "          [--odom-rate LO:HI] [--odom-ticks M:B] [--odom-delivery late:S|burst:N]...\n"
      "       %s --cloud-scenario NAME --convention NAME --bag OUT.bag --truth OUT.truth [--noise]\n"
      "          [--seed N] [--tf-rate HZ] [--tf-margin S] [--duration S] [--latency S] [--odom-* as above]\n"
      "  --list              the planar scenarios (LaserScan on /scan): the paper's, calibration's, smooth\n"
      "  --list-paper        the paper's 19, then 5 LDS-01 ones in a small room (docs/RESULTS.md)\n"
      "  --list-calibration  the drives for timing calibration (SENSOR/normal|high/turns, "
      "SENSOR/normal/spin|circle)\n"
      "  --list-smooth       speed and turn rate changing between samples too (SENSOR/normal|high/smooth)\n"
      "  --list-clouds       the multi-line scenarios (PointCloud2 on /points, frame lidar)\n"
      "  --list-cloud-smooth multi-line, speed and turn rate changing between samples too\n"
      "                      (SENSOR/normal|high|rough/smooth)\n"
      "  --list-conventions  the drivers' cloud layouts for --convention\n"
      "  --list-drivers      the 2D drivers for --driver\n"
      "  --driver NAME       the scans as that 2D driver writes them (docs/REAL_ROBOTS.md): its sensor\n"
      "                      (beams, rate, field of view) and timing convention, on the sensor's\n"
      "                      SENSOR/normal/turns drive, or with --scenario on that one's motion and\n"
      "                      world; no timing-fault options with it but --stamp-error S, which then\n"
      "                      adds S to the driver's stamp (a link's latency)\n"
      "  --tf-margin S       odometry from S before the first scan (sweep) to S after the last (default "
      "0.1)\n"
      "  --odom-noise R      odometry (/tf odom -> base_link, /odom) off by R relative per 20 ms step in\n"
      "                      x, y and yaw, a random walk away from the truth (default 0: perfect)\n"
      "  --odom-seed N       seed of the odometry noise and timing (default 1; --seed is the range's)\n"
      "  --odom-yaw-scale F  odometry reports F x the true rotation (default 1; with or without noise)\n"
      "odometry samples as robots produce them (recorded in the truth file; every --odom-* option works\n"
      "with --cloud-scenario too, on the wheels' x, y and yaw: z, roll and pitch stay true):\n"
      "  --odom-jitter S     each stamp off the sample's true time by a uniform error in [-S, S]; the\n"
      "                      pose stays the true time's (a driver stamping on receipt)\n"
      "  --odom-rate LO:HI   irregular: each next sample 1/HI to 1/LO s (uniform) after the last\n"
      "                      (instead of --tf-rate's grid)\n"
      "  --odom-ticks M:B    diff-drive encoders: each wheel's travel in whole ticks of M m, wheel base\n"
      "                      B m; poses integrated from the tick counts (heading steps M / B rad)\n"
      "  --odom-delivery late:S   recorded S s after the stamp\n"
      "  --odom-delivery burst:N  recorded N samples at a time, at the last one's record time\n"
      "timing faults of the /scan messages (planar scenarios only; recorded in the truth file):\n"
      "  --stamp-error S     header.stamp = true time of the earliest beam + S (time_offset = -S)\n"
      "  --stamp-at-end      stamped at the latest beam: S = (beams - 1) * true time_increment\n"
      "  --reversed          beam i truly measured at t0 + (n - 1 - i) dt, the message claims index\n"
      "                      order; the stamp refers to the earliest beam, index n - 1\n"
      "  --time-increment-factor F  time_increment = F * the true one (0: unknown)\n"
      "  --zero-scan-time    scan_time = 0\n",
      program, program, program);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lidar_deskew;
  std::string scenario_name, cloud_scenario_name, convention_name, driver_name, bag_path, truth_path;
  bool clockwise = false, stamp_at_end = false, stamp_error_given = false, any_fault = false;
  double duration = 0.0;
  sim::SimBagOptions options;
  sim::CloudBagOptions cloud_options;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "--list" || arg == "--list-paper" || arg == "--list-calibration" || arg == "--list-smooth") {
      const std::vector<sim::Scenario> scenarios = arg == "--list"               ? sim::planarScenarios()
                                                   : arg == "--list-paper"       ? sim::paperScenarios()
                                                   : arg == "--list-calibration" ? sim::calibrationScenarios()
                                                                                 : sim::smoothScenarios();
      for (const sim::Scenario& scenario : scenarios)
        std::printf("%s\n", scenario.name.c_str());
      return 0;
    } else if (arg == "--list-clouds" || arg == "--list-cloud-smooth") {
      for (const sim::CloudScenario& scenario :
           arg == "--list-clouds" ? sim::cloudScenarios() : sim::cloudSmoothScenarios())
        std::printf("%s\n", scenario.name.c_str());
      return 0;
    } else if (arg == "--list-conventions") {
      for (const std::string& name : sim::cloudConventionNames())
        std::printf("%s\n", name.c_str());
      return 0;
    } else if (arg == "--list-drivers") {
      for (const std::string& name : sim::laserDriverNames())
        std::printf("%s\n", name.c_str());
      return 0;
    } else if (arg == "--driver" && has_value) {
      driver_name = argv[++a];
    } else if (arg == "--scenario" && has_value) {
      scenario_name = argv[++a];
    } else if (arg == "--cloud-scenario" && has_value) {
      cloud_scenario_name = argv[++a];
    } else if (arg == "--convention" && has_value) {
      convention_name = argv[++a];
    } else if (arg == "--bag" && has_value) {
      bag_path = argv[++a];
    } else if (arg == "--truth" && has_value) {
      truth_path = argv[++a];
    } else if (arg == "--duration" && has_value) {
      duration = std::atof(argv[++a]);
    } else if (arg == "--latency" && has_value) {
      cloud_options.latency = std::atof(argv[++a]);
    } else if (arg == "--clockwise") {
      clockwise = true;
    } else if (arg == "--noise") {
      options.noise = true;
    } else if (arg == "--seed" && has_value) {
      options.seed = static_cast<unsigned>(std::strtoul(argv[++a], nullptr, 10));
    } else if (arg == "--tf-rate" && has_value) {
      options.tf_rate = std::atof(argv[++a]);
    } else if (arg == "--tf-margin" && has_value) {
      options.tf_margin = std::atof(argv[++a]);
    } else if (arg == "--odom-noise" && has_value) {
      options.odom_noise = std::atof(argv[++a]);
    } else if (arg == "--odom-yaw-scale" && has_value) {
      options.odom_yaw_scale = std::atof(argv[++a]);
    } else if (arg == "--odom-seed" && has_value) {
      options.odom_noise_seed = static_cast<unsigned>(std::strtoul(argv[++a], nullptr, 10));
    } else if (arg == "--odom-jitter" && has_value) {
      options.odom_timing.jitter = std::atof(argv[++a]);
    } else if ((arg == "--odom-rate" || arg == "--odom-ticks") && has_value) {
      double first = 0.0, second = 0.0;
      char end = 0;
      if (std::sscanf(argv[++a], "%lf:%lf%c", &first, &second, &end) != 2) {
        std::fprintf(stderr, "%s takes two numbers A:B, not '%s'\n", arg.c_str(), argv[a]);
        return 2;
      }
      if (arg == "--odom-rate") {
        options.odom_timing.rate_min = first;
        options.odom_timing.rate_max = second;
      } else {
        options.odom_timing.tick = first;
        options.odom_timing.wheel_base = second;
      }
    } else if (arg == "--odom-delivery" && has_value) {
      const std::string value = argv[++a];
      char* end = nullptr;
      if (value.rfind("late:", 0) == 0) {
        options.odom_timing.late = std::strtod(value.c_str() + 5, &end);
      } else if (value.rfind("burst:", 0) == 0) {
        options.odom_timing.burst = static_cast<int>(std::strtol(value.c_str() + 6, &end, 10));
      }
      if (end == nullptr || *end != '\0' || end == value.c_str() + value.find(':') + 1) {
        std::fprintf(stderr, "--odom-delivery takes late:S or burst:N, not '%s'\n", value.c_str());
        return 2;
      }
    } else if (arg == "--stamp-error" && has_value) {
      options.timing_fault.stamp_error = std::atof(argv[++a]);
      stamp_error_given = any_fault = true;
    } else if (arg == "--stamp-at-end") {
      stamp_at_end = any_fault = true;
    } else if (arg == "--reversed") {
      options.timing_fault.reversed = any_fault = true;
    } else if (arg == "--time-increment-factor" && has_value) {
      options.timing_fault.time_increment_factor = std::atof(argv[++a]);
      any_fault = true;
    } else if (arg == "--zero-scan-time") {
      options.timing_fault.zero_scan_time = any_fault = true;
    } else {
      return usage(argv[0]);
    }
  }
  const bool cloud = !cloud_scenario_name.empty();
  const bool driver = !driver_name.empty();
  if ((scenario_name.empty() && !driver) == !cloud || bag_path.empty() || truth_path.empty())
    return usage(argv[0]);
  if (driver && (cloud || stamp_at_end || options.timing_fault.reversed ||
                 options.timing_fault.time_increment_factor != 1.0 || options.timing_fault.zero_scan_time)) {
    std::fprintf(stderr,
                 "deskew_simulate: --driver sets the scans' timing; give it with neither --cloud-scenario "
                 "nor a timing fault but --stamp-error (--stamp-at-end, --reversed, --time-increment-factor, "
                 "--zero-scan-time)\n");
    return 2;
  }
  if (cloud && convention_name.empty()) {
    std::fprintf(stderr, "deskew_simulate: --cloud-scenario needs --convention (--list-conventions)\n");
    return 2;
  }
  if (cloud && clockwise) {
    std::fprintf(stderr,
                 "deskew_simulate: --clockwise is for planar scenarios (--scenario), not --cloud-scenario\n");
    return 2;
  }
  if (!cloud && !convention_name.empty()) {
    std::fprintf(stderr, "deskew_simulate: --convention is for --cloud-scenario, not --scenario\n");
    return 2;
  }
  if (!(options.tf_rate > 0.0)) {
    std::fprintf(stderr, "--tf-rate must be > 0 Hz\n");
    return 2;
  }
  if (!(options.tf_margin >= 0.0)) {
    std::fprintf(stderr, "--tf-margin must be >= 0 s\n");
    return 2;
  }
  if (!(options.odom_noise >= 0.0) || !std::isfinite(options.odom_noise)) {
    std::fprintf(stderr, "--odom-noise must be finite and >= 0\n");
    return 2;
  }
  if (!(options.odom_yaw_scale > 0.0) || !std::isfinite(options.odom_yaw_scale)) {
    std::fprintf(stderr, "--odom-yaw-scale must be finite and > 0\n");
    return 2;
  }
  try {
    options.odom_timing.validate();
  } catch (const std::invalid_argument& error) {
    std::fprintf(stderr, "deskew_simulate: %s\n", error.what());
    return 2;
  }
  if (cloud && any_fault) {
    std::fprintf(stderr,
                 "deskew_simulate: timing faults (--stamp-error, --stamp-at-end, --reversed, "
                 "--time-increment-factor, --zero-scan-time) are for planar scenarios (--scenario), not "
                 "--cloud-scenario\n");
    return 2;
  }
  if (stamp_at_end && stamp_error_given) {
    std::fprintf(stderr, "deskew_simulate: give --stamp-error or --stamp-at-end, not both\n");
    return 2;
  }
  try {
    if (cloud) {
      cloud_options.convention = sim::cloudConventionFromName(convention_name);
      cloud_options.noise = options.noise;
      cloud_options.seed = options.seed;
      cloud_options.tf_rate = options.tf_rate;
      cloud_options.duration = duration;
      cloud_options.tf_margin = options.tf_margin;
      cloud_options.odom_noise = options.odom_noise;
      cloud_options.odom_noise_seed = options.odom_noise_seed;
      cloud_options.odom_yaw_scale = options.odom_yaw_scale;
      cloud_options.odom_timing = options.odom_timing;
      sim::writeCloudBag(sim::findCloudScenario(cloud_scenario_name), cloud_options, bag_path, truth_path);
      return 0;
    }
    sim::Scenario scenario;
    if (driver) {
      const sim::LaserDriver laser_driver = sim::laserDriverFromName(driver_name);
      scenario = sim::driverScenario(laser_driver);
      if (!scenario_name.empty()) {  // that scenario's motion and world with the driver's sensor
        const sim::LidarModel lidar = scenario.lidar;
        scenario = sim::findScenario(scenario_name);
        scenario.lidar = lidar;
        scenario.name += "/" + driver_name;
      }
    } else {
      scenario = sim::findScenario(scenario_name);
    }
    if (clockwise) {
      scenario = sim::clockwiseVariant(scenario);
    }
    if (duration > 0.0) {  // longer recordings (benchmarks); the last motion piece goes on
      scenario.duration = duration;
    }
    if (driver) {  // --stamp-error adds a latency to the driver's own stamp
      const double latency = options.timing_fault.stamp_error;
      options.timing_fault = sim::driverTiming(sim::laserDriverFromName(driver_name), scenario.lidar);
      options.timing_fault.stamp_error += latency;
    }
    if (stamp_at_end) {
      options.timing_fault.stamp_error = sim::TimingFault::stampedAtEnd(scenario.lidar).stamp_error;
    }
    sim::writeSimulationBag(scenario, options, bag_path, truth_path);
  } catch (const std::exception& error) {
    std::fprintf(stderr, "deskew_simulate: %s\n", error.what());
    return 1;
  }
  return 0;
}
