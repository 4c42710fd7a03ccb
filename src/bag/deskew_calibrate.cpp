// deskew_calibrate: estimates a planar LIDAR's timing from a recording (docs/CALIBRATION.md).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <string>
#include <vector>

#include "lidar_deskew/bag/bag_calibrate.h"

using namespace lidar_deskew;

namespace {

void printUsage(std::FILE* to, const char* program) {
  std::fprintf(
      to,
      "usage: %s IN.bag [--scan-topic T] [--output FILE.yaml] [--curve FILE.csv] [--fixed-frame F]\n"
      "          [--base-frame B]\n"
      "\n"
      "Estimates from a recording in which the robot turns the timing of a LaserScan topic: the offset\n"
      "between header.stamp and the first beam's true time (time_offset, or stamp_at: end), the beams'\n"
      "order in time (beam_order) and, when time_increment and scan_time are 0 or disagree with the\n"
      "data, the revolution period (scan_period, use_scan_period). Prints each with its uncertainty\n"
      "and how well overlapping scans agree before and after; writes the parameters to FILE.yaml, which\n"
      "`roslaunch lidar_deskew deskew.launch params:=FILE.yaml` and `deskew_bag --params FILE.yaml` read.\n"
      "What the recording cannot tell is said, not guessed. Exit status:\n"
      "  0  the whole timing told (written, or the message's fits)\n"
      "  4  the beam order and the period told and written, the offset not (the motion was too uniform,\n"
      "     the score too flat, the odometry too coarse, or no clear minimum): the message's offset is kept\n"
      "  3  nothing told (too little turning or a score too flat, too few overlapping pairs, the beam\n"
      "     order or the period undecided, no fit better than raw): nothing written\n"
      "  1  the bag, topic or tf could not be read; 2  bad arguments\n"
      "  --scan-topic T     the LaserScan topic (default: the bag's only one)\n"
      "  --output FILE      the parameter file to write (default: print only)\n"
      "  --curve FILE       write the score against the offset (CSV) for the chosen order and period\n"
      "  --turning-rate R   [rad/s] a scan turns when its base turns this fast (default 0.3); the\n"
      "                     offset needs pairs whose turn rates differ by R, the order turning scans\n"
      "  --scan-period S    [s] one revolution, when you know it: not estimated (written as scan_period)\n"
      "  --beam-order O     as_message or reversed, when you know it: not estimated\n"
      "  --fixed-frame F    the frame the base moves in (default odom)\n"
      "  --base-frame B     the robot's base frame (default base_link)\n"
      "  --cloud-topic T    refused: clouds carry their own per-point times (set time_offset by hand)\n"
      "  --help             this text\n",
      program);
}

int usageError(const char* program, const std::string& message) {
  std::fprintf(stderr, "deskew_calibrate: %s\n", message.c_str());
  printUsage(stderr, program);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  bag::CalibrateOptions options;
  std::string output, curve;
  std::map<std::string, std::string> frames;
  std::vector<std::string> positional;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--help" || arg == "-h") {
      printUsage(stdout, argv[0]);
      return 0;
    }
    if (arg == "--scan-topic" || arg == "--output" || arg == "--fixed-frame" || arg == "--base-frame" ||
        arg == "--cloud-topic" || arg == "--curve" || arg == "--turning-rate" || arg == "--scan-period" ||
        arg == "--beam-order") {
      if (a + 1 >= argc)
        return usageError(argv[0], arg + " needs a value");
      const std::string value = argv[++a];
      if (arg == "--scan-topic")
        options.scan_topic = value;
      else if (arg == "--output")
        output = value;
      else if (arg == "--curve")
        curve = value;
      else if (arg == "--turning-rate") {
        char* end = nullptr;
        options.fit.turning_rate = std::strtod(value.c_str(), &end);
        if (end == value.c_str() || *end != '\0' || !(options.fit.turning_rate > 0.0))
          return usageError(argv[0], "--turning-rate: a positive number of rad/s, got " + value);
      } else if (arg == "--scan-period") {
        char* end = nullptr;
        options.fit.given_period = std::strtod(value.c_str(), &end);
        if (end == value.c_str() || *end != '\0' || !(options.fit.given_period > 0.0) ||
            options.fit.given_period > 10.0)
          return usageError(argv[0], "--scan-period: one revolution in s (0-10], got " + value);
      } else if (arg == "--beam-order") {
        if (value == "as_message")
          options.fit.given_order = core::BeamOrder::kAsMessage;
        else if (value == "reversed")
          options.fit.given_order = core::BeamOrder::kReversed;
        else
          return usageError(argv[0], "--beam-order: as_message or reversed, got " + value);
      } else if (arg == "--fixed-frame")
        frames["fixed_frame"] = value;
      else if (arg == "--base-frame")
        frames["base_frame"] = value;
      else
        return usageError(argv[0],
                          "--cloud-topic: calibrating PointCloud2 topics is not supported; a cloud's "
                          "per-point time field carries its timing (a fixed latency: the time_offset "
                          "parameter)");
    } else if (arg.rfind("--", 0) == 0) {
      return usageError(argv[0], "unknown option " + arg);
    } else {
      positional.push_back(arg);
    }
  }
  if (positional.size() != 1)
    return usageError(argv[0],
                      "expected one IN.bag, got " + std::to_string(positional.size()) + " file name(s)");
  options.input = positional[0];
  try {
    options.params = ros_adapter::DeskewParams::load(ros_adapter::TextParams(frames));
    const auto started = std::chrono::steady_clock::now();
    options.progress = [started](const std::string& stage) {
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      std::fprintf(stderr, "deskew_calibrate: [%.0f s] %s ...\n", elapsed, stage.c_str());
    };
    const bag::Calibration calibration = bag::calibrateBag(options);
    std::printf("deskew_calibrate: %s\n", bag::describe(calibration).c_str());
    if (!curve.empty() && !calibration.estimate.coarse_curve.empty()) {
      bag::writeCurve(calibration, curve);
      std::printf("wrote %s\n", curve.c_str());
    }
    if (!calibration.estimate.told) {
      std::printf("nothing written\n");
      return 3;
    }
    if (!output.empty()) {
      bag::writeTimingParams(calibration, options.input, output);
      std::printf(
          "wrote %s%s\n", output.c_str(),
          calibration.estimate.offset_told ? "" : " (the beam order and period; the offset is not told)");
    }
    if (!calibration.estimate.offset_told)
      return 4;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "deskew_calibrate: %s\n", error.what());
    return 1;
  }
  return 0;
}
