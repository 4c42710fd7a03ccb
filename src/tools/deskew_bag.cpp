// deskew_bag: reprocesses a recorded bag with the same parameters, core and tf adapter as the live
// node. No roscore needed.
//
//   deskew_bag IN.bag OUT.bag [--scan-topic T]... [--replace] [--mount-from tf|tf_static]
//              [--compression none|bz2|lz4] [--consistency] [--consistency-figure CSV] [--quiet]
//              [--PARAMETER VALUE]...
// PARAMETER is any of the node's parameters (README), e.g. --fixed-frame odom --reference end.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <exception>
#include <map>
#include <string>

#include "lidar_deskew/ros/bag_deskew.h"

namespace {

using namespace lidar_deskew::ros_adapter;

int usage(const char* program) {
  std::fprintf(stderr,
               "usage: %s IN.bag OUT.bag [--scan-topic T]... [--replace] [--mount-from tf|tf_static]\n"
               "          [--compression none|bz2|lz4] [--consistency] [--consistency-figure CSV] [--quiet]\n"
               "          [--PARAMETER VALUE]...\n"
               "PARAMETER: any of the node's parameters, with - or _:",
               program);
  for (const std::string& name : DeskewParams::names())
    std::fprintf(stderr, " %s", name.c_str());
  std::fprintf(stderr, "\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  BagDeskewOptions options;
  options.scan_topics.clear();
  std::map<std::string, std::string> parameters;
  bool quiet = false, consistency = false;
  std::string consistency_figure;
  std::vector<std::string> positional;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "--scan-topic" && has_value) {
      options.scan_topics.push_back(argv[++a]);
    } else if (arg == "--replace") {
      options.replace = true;
    } else if (arg == "--mount-from" && has_value) {
      const std::string from = argv[++a];
      if (from != "tf" && from != "tf_static")
        return usage(argv[0]);
      options.mount_from = from == "tf" ? MountSource::kTf : MountSource::kTfStatic;
    } else if (arg == "--compression" && has_value) {
      options.compression = argv[++a];
    } else if (arg == "--consistency") {
      consistency = true;
    } else if (arg == "--consistency-figure" && has_value) {
      consistency = true;
      consistency_figure = argv[++a];
    } else if (arg == "--quiet") {
      quiet = true;
    } else if (arg.rfind("--", 0) == 0 && has_value) {
      std::string name = arg.substr(2);
      std::replace(name.begin(), name.end(), '-', '_');
      const auto& names = DeskewParams::names();
      if (std::find(names.begin(), names.end(), name) == names.end())
        return usage(argv[0]);
      parameters[name] = argv[++a];
    } else if (arg.rfind("--", 0) != 0) {
      positional.push_back(arg);
    } else {
      return usage(argv[0]);
    }
  }
  if (positional.size() != 2)
    return usage(argv[0]);
  options.input = positional[0];
  options.output = positional[1];
  if (options.scan_topics.empty())
    options.scan_topics.push_back("/scan");

  const bool terminal = isatty(STDERR_FILENO) && !quiet;
  const auto started = std::chrono::steady_clock::now();
  options.inform = [&](const std::string& note) {
    if (!quiet)
      std::fprintf(stderr, "%s%s\n", terminal ? "\r\033[K" : "", note.c_str());
  };
  if (terminal) {
    options.progress = [&](double fraction, std::size_t scans) {
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      const int filled = static_cast<int>(30 * fraction);
      const double eta = fraction > 0.0 ? elapsed * (1.0 - fraction) / fraction : 0.0;
      std::fprintf(stderr, "\r[%-30s] %3.0f%%  %6.0f scans/s  ETA %4.0f s", std::string(filled, '#').c_str(),
                   100.0 * fraction, scans / std::max(elapsed, 1e-9), eta);
      if (fraction >= 1.0)
        std::fprintf(stderr, "\n");
    };
  }
  try {
    options.params = DeskewParams::load(TextParams(parameters));
    const BagDeskewSummary summary = deskewBag(options);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    std::printf("deskew_bag: %s -> %s in %.2f s\n", options.input.c_str(), options.output.c_str(), elapsed);
    std::printf(
        "  %zu messages copied; %zu scans: %zu corrected, %zu passed through, dropped %zu malformed, "
        "%zu without tf\n",
        summary.messages, summary.scans, summary.corrected, summary.passed_through, summary.dropped_invalid,
        summary.dropped_tf);
    std::printf("  %s\n", summary.mount.c_str());
    if (consistency) {
      for (const std::string& topic : options.scan_topics) {
        const std::string corrected = options.replace ? topic : topic + "_deskewed";
        const std::string raw = options.replace ? topic + "_raw" : topic;
        const ConsistencyReport report = measureConsistency(options.output, raw, corrected, options.params,
                                                            options.mount_from, 0.1, 0.3, consistency_figure);
        std::printf(
            "  %s while turning (%zu scan pairs): consecutive scans %.1f mm apart raw, %.1f mm corrected\n",
            topic.c_str(), report.turning_pairs, report.raw_mm, report.corrected_mm);
      }
    }
  } catch (const std::exception& error) {
    if (terminal)
      std::fprintf(stderr, "\n");
    std::fprintf(stderr, "deskew_bag: %s\n", error.what());
    return 1;
  }
  return 0;
}
