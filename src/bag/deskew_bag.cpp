// deskew_bag: reprocesses a recorded bag through the live node's pipeline (docs/DESIGN.md §2). No
// roscore needed. `deskew_bag --help` prints the usage.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <map>
#include <string>

#include "lidar_deskew/bag/bag_deskew.h"
#include "lidar_deskew/eval/pair_consistency.h"
#include "lidar_deskew/eval/shape_consistency.h"

namespace {

using namespace lidar_deskew;

std::atomic<bool> interrupted{false};

extern "C" void onSignal(int /*signal*/) {
  interrupted.store(true);
}

void printUsage(std::FILE* to, const char* program) {
  std::fprintf(
      to,
      "usage: %s IN.bag OUT.bag [--scan-topic T]... [--cloud-topic T]... [--replace]\n"
      "          [--compression none|bz2|lz4] [--params FILE.yaml]\n"
      "          [--consistency] [--consistency-figure CSV] [--quiet] [--PARAMETER VALUE]...\n"
      "\n"
      "Corrects the LaserScans and PointCloud2s of IN.bag with the live nodes' pipeline; writes every\n"
      "message of IN.bag as it was plus, for a scan, <topic>_deskewed (LaserScan) and\n"
      "<topic>_deskewed_points (PointCloud2), for a cloud, <topic>_deskewed (PointCloud2).\n"
      "  --scan-topic T      a LaserScan topic to correct (repeatable); default: the bag's LaserScan\n"
      "                      topics (or, with none, its PointCloud2 topics)\n"
      "  --cloud-topic T     a PointCloud2 topic to correct (repeatable); its per-point time field is\n"
      "                      found alone (t, time, timestamp, time_stamp, offset_time, stamps)\n"
      "  --replace           corrected scan on T itself, the raw one on T_raw\n"
      "  --compression C     of OUT.bag: none (default), bz2 or lz4\n"
      "  --params FILE.yaml  parameters from a file, as the node's launch `params:=FILE` (e.g. one\n"
      "                      deskew_calibrate wrote); --PARAMETER options win over it\n"
      "  --consistency       print how well overlapping scans agree, raw and corrected (robust\n"
      "                      point-to-line distance over every overlapping pair, with its spread),\n"
      "                      their shapes (scans aligned by a free scan match, corrected / raw) and\n"
      "                      whether tf's rotation fits the scans; warns where it does not or where\n"
      "                      correction makes shapes worse\n"
      "  --consistency-figure CSV   the same, and the points of the pair turning most to CSV\n"
      "  --quiet             no notes, no progress bar\n"
      "  --help              this text\n"
      "PARAMETER: any of the node's parameters (docs/PARAMETERS.md), with - or _:",
      program);
  const auto& live_only = ros_adapter::DeskewParams::liveOnlyNames();
  for (const std::string& name : ros_adapter::DeskewParams::names()) {
    if (std::find(live_only.begin(), live_only.end(), name) == live_only.end())
      std::fprintf(to, " %s", name.c_str());
  }
  std::fprintf(to, "\n(live only, refused here:");
  for (const std::string& name : live_only)
    std::fprintf(to, " %s", name.c_str());
  std::fprintf(to, ")\n");
}

int usageError(const char* program, const std::string& message) {
  std::fprintf(stderr, "deskew_bag: %s\n", message.c_str());
  printUsage(stderr, program);
  return 2;
}

/// "dropped 3: tf never reached the sweep's end (2), no laser mount in tf (1)"; empty when none.
std::string byCause(const char* what, const std::map<std::string, std::uint64_t>& causes) {
  std::uint64_t total = 0;
  std::string list;
  for (const auto& [cause, count] : causes) {
    total += count;
    list += (list.empty() ? "" : ", ") + cause + " (" + std::to_string(count) + ")";
  }
  return total == 0 ? "" : std::string(what) + " " + std::to_string(total) + ": " + list;
}

void printCounters(const std::string& topic, const ros_adapter::PipelineCounters& counters) {
  std::string text;
  for (const auto& [name, value] : ros_adapter::namedCounters(counters))
    text += (text.empty() ? "" : ", ") + name + " " + std::to_string(value);
  std::printf("  %s: %s\n", topic.c_str(), text.c_str());
  for (const auto& [what, causes] : {std::pair{"dropped", &counters.dropped_by_cause},
                                     std::pair{"passed through", &counters.passed_by_cause}}) {
    const std::string line = byCause(what, *causes);
    if (!line.empty())
      std::printf("    %s\n", line.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  bag::BagDeskewOptions options;
  std::map<std::string, std::string> parameters;
  bool quiet = false, consistency = false;
  std::string consistency_figure, params_file;
  std::vector<std::string> positional;
  const auto& names = ros_adapter::DeskewParams::names();
  const auto& live_only = ros_adapter::DeskewParams::liveOnlyNames();
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    const bool has_value = a + 1 < argc;
    if (arg == "--help" || arg == "-h") {
      printUsage(stdout, argv[0]);
      return 0;
    } else if (arg == "--replace") {
      options.replace = true;
    } else if (arg == "--consistency") {
      consistency = true;
    } else if (arg == "--quiet") {
      quiet = true;
    } else if (arg == "--scan-topic" || arg == "--cloud-topic" || arg == "--compression" ||
               arg == "--consistency-figure" || arg == "--params") {
      if (!has_value)
        return usageError(argv[0], arg + " needs a value");
      const std::string value = argv[++a];
      if (arg == "--scan-topic") {
        options.scan_topics.push_back(value);
      } else if (arg == "--cloud-topic") {
        options.cloud_topics.push_back(value);
      } else if (arg == "--compression") {
        options.compression = value;
      } else if (arg == "--params") {
        params_file = value;
      } else {
        consistency = true;
        consistency_figure = value;
      }
    } else if (arg.rfind("--", 0) == 0) {
      std::string name = arg.substr(2);
      std::replace(name.begin(), name.end(), '-', '_');
      if (std::find(live_only.begin(), live_only.end(), name) != live_only.end()) {
        return usageError(argv[0],
                          "--" + name +
                              " is a parameter of the live node only (offline, tf that comes after a "
                              "scan is in the bag, so nothing is extrapolated; there is no input "
                              "subscription and no diagnostics: the summary holds their counters)");
      }
      if (std::find(names.begin(), names.end(), name) == names.end())
        return usageError(argv[0], "unknown option " + arg);
      if (!has_value)
        return usageError(argv[0], arg + " needs a value");
      parameters[name] = argv[++a];
    } else {
      positional.push_back(arg);
    }
  }
  if (positional.size() != 2) {
    return usageError(argv[0],
                      "expected IN.bag OUT.bag, got " + std::to_string(positional.size()) + " file name(s)");
  }
  options.input = positional[0];
  options.output = positional[1];

  // Ctrl-C and SIGTERM stop the run cleanly: the temporary output is removed.
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  options.interrupted = &interrupted;

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
    if (!params_file.empty()) {
      // The node's parameter file: its live-only parameters mean nothing here and are left out.
      std::map<std::string, std::string> from_file = ros_adapter::readParamFile(params_file);
      std::vector<std::string> given;
      for (const auto& entry : from_file)
        given.push_back(entry.first);
      const std::vector<std::string> unknown = ros_adapter::DeskewParams::unknownNames(given);
      if (!unknown.empty()) {
        std::string list;
        for (const std::string& name : unknown)
          list += (list.empty() ? "" : ", ") + name;
        throw std::runtime_error(params_file + ": unknown parameter(s): " + list);
      }
      for (const std::string& name : live_only)
        from_file.erase(name);
      parameters.insert(from_file.begin(), from_file.end());  // the command line's win
    }
    // Offline nothing waits for the look-ahead's samples but the recording: the twist fit reads all it
    // can (1 s, docs/DESIGN.md §5), unless told otherwise.
    parameters.emplace("fit_look_ahead", std::to_string(core::kFitHorizon));
    options.params = ros_adapter::DeskewParams::load(ros_adapter::TextParams(parameters));
    const bag::BagDeskewSummary summary = bag::deskewBag(options);
    // The output is complete: from here on Ctrl-C ends the program as usual.
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    std::printf("deskew_bag: %s -> %s in %.2f s, %zu messages copied\n", options.input.c_str(),
                options.output.c_str(), elapsed, summary.messages);
    for (const auto& [topic, counters] : summary.counters)
      printCounters(topic, counters);
    if (consistency) {
      for (const std::string& topic : summary.chosen_topics) {
        if (std::find(summary.cloud_topics.begin(), summary.cloud_topics.end(), topic) !=
            summary.cloud_topics.end()) {
          // The consistency and shape measures are of planar scans: say so rather than print nothing.
          std::printf("  %s: no consistency measure for PointCloud2 topics (it aligns planar scans); "
                      "on a simulated recording, deskew_metrics --cloud BAG TRUTH measures clouds against the truth\n",
                      topic.c_str());
          continue;
        }
        const std::string corrected = options.replace ? topic : topic + "_deskewed";
        const std::string raw = options.replace ? topic + "_raw" : topic;
        const eval::ConsistencyReport report =
            eval::measureConsistency(options.output, raw, corrected, options.params, 0.3, consistency_figure);
        std::printf(
            "  %s consistency (robust point-to-line distance between overlapping scans):\n"
            "    every pair: raw %s, corrected %s\n"
            "    pairs with a scan turning at 0.3 rad/s or faster: raw %s, corrected %s\n",
            topic.c_str(), eval::formatConsistency(report.raw).c_str(),
            eval::formatConsistency(report.corrected).c_str(),
            eval::formatConsistency(report.raw_turning).c_str(),
            eval::formatConsistency(report.corrected_turning).c_str());
        // Shapes: raw scans from the input, corrected here under the same parameters.
        const eval::ShapeReport shapes = eval::measureShapes(options.input, topic, options.params);
        std::printf(
            "  %s shapes (scans up to 1.5 s apart whose turn rates differ by 0.3 rad/s or more, aligned by a "
            "free rigid scan match):\n"
            "    corrected / raw: %s\n"
            "    rotation between consecutive scans, scan matching / tf: %s\n",
            topic.c_str(), eval::formatShapes(shapes.shapes).c_str(),
            eval::formatRotation(shapes.rotation).c_str());
        for (const std::string& warning : shapes.warnings)
          std::printf("  warning: %s: %s\n", topic.c_str(), warning.c_str());
      }
    }
  } catch (const bag::Interrupted& error) {
    std::fprintf(stderr, "%sdeskew_bag: %s\n", terminal ? "\n" : "", error.what());
    return 130;
  } catch (const std::exception& error) {
    if (terminal)
      std::fprintf(stderr, "\n");
    std::fprintf(stderr, "deskew_bag: %s\n", error.what());
    return 1;
  }
  return 0;
}
