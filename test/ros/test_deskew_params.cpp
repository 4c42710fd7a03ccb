// The parameter table (DeskewParams::specs) is the one place parameters are written: config/deskew.yaml
// and the table of docs/PARAMETERS.md must say the same, and every bound it states is enforced.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <vector>

#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::ros_adapter {
namespace {

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// config/deskew.yaml: every parameter, with its default, and nothing else.
TEST(Params, ConfigFileListsEveryParameterWithItsDefault) {
  const std::string yaml = readFile(std::string(LIDAR_DESKEW_SOURCE_DIR) + "/config/deskew.yaml");
  std::map<std::string, std::string> values;
  const std::regex line(R"(^([a-z_]+):\s*([^\s#]+))");
  std::istringstream lines(yaml);
  for (std::string text; std::getline(lines, text);) {
    std::smatch match;
    if (std::regex_search(text, match, line))
      values[match[1]] = match[2] == "\"\"" ? "" : match[2].str();  // "" is the empty string
  }
  EXPECT_EQ(values.size(), DeskewParams::specs().size());
  for (const ParamSpec& spec : DeskewParams::specs()) {
    ASSERT_TRUE(values.count(spec.name)) << spec.name << " is missing from config/deskew.yaml";
    EXPECT_EQ(values[spec.name], spec.default_value) << spec.name;
  }
  // And the file loads to the defaults.
  const DeskewParams loaded = DeskewParams::load(TextParams(values));
  const DeskewParams defaults;
  EXPECT_EQ(loaded.fixed_frame, defaults.fixed_frame);
  EXPECT_EQ(loaded.tf_timeout, defaults.tf_timeout);
  EXPECT_EQ(loaded.deskew.knot_interval, defaults.deskew.knot_interval);
  EXPECT_EQ(loaded.queue_size, defaults.queue_size);
}

// docs/PARAMETERS.md's table: a row per parameter, with the default and unit of the table in code.
TEST(Params, DocumentedTableMatchesTheCode) {
  const std::string readme = readFile(std::string(LIDAR_DESKEW_SOURCE_DIR) + "/docs/PARAMETERS.md");
  struct Row {
    std::string default_value, unit, bounds, live;
  };
  std::map<std::string, Row> rows;
  // A row: | `name` | default | unit | allowed | live | meaning |, cells trimmed of spaces and backquotes.
  std::istringstream lines(readme);
  for (std::string text; std::getline(lines, text);) {
    if (text.rfind("| `", 0) != 0)
      continue;
    std::vector<std::string> cells;
    std::istringstream cell_stream(text.substr(1));
    for (std::string cell; std::getline(cell_stream, cell, '|');) {
      const auto first = cell.find_first_not_of(" `"), last = cell.find_last_not_of(" `");
      cells.push_back(first == std::string::npos ? "" : cell.substr(first, last - first + 1));
    }
    if (cells.size() >= 6)
      rows[cells[0]] = {cells[1], cells[2], cells[3], cells[4]};
  }
  for (const ParamSpec& spec : DeskewParams::specs()) {
    ASSERT_TRUE(rows.count(spec.name)) << spec.name << " has no row in docs/PARAMETERS.md's table";
    const std::string& documented = rows[spec.name].default_value;
    if (std::string(spec.type) == "double") {
      EXPECT_DOUBLE_EQ(std::stod(documented), std::stod(spec.default_value)) << spec.name;
    } else {
      EXPECT_EQ(documented, spec.default_value) << spec.name;
    }
    EXPECT_EQ(rows[spec.name].unit, spec.unit) << spec.name;
    EXPECT_EQ(rows[spec.name].bounds, spec.bounds()) << spec.name;
    // live: reconfigurable on both nodes (yes) or on the one whose input it applies to.
    const char* live = spec.input == ros_adapter::Input::kScans    ? "scans"
                       : spec.input == ros_adapter::Input::kClouds ? "clouds"
                                                                   : "yes";
    EXPECT_EQ(rows[spec.name].live, spec.reconfigurable ? live : "") << spec.name;
  }
}

// Every bound in the table is enforced, named in the error: just inside passes, just outside fails.
TEST(Params, EveryBoundIsEnforced) {
  for (const ParamSpec& spec : DeskewParams::specs()) {
    const std::string type = spec.type;
    if (type != "double" && type != "int")
      continue;
    const auto load = [&](double value) {
      std::ostringstream text;
      text.precision(17);
      text << (type == "int" ? static_cast<double>(static_cast<long>(value)) : value);
      return DeskewParams::load(TextParams(std::map<std::string, std::string>{{spec.name, text.str()}}));
    };
    const double step = type == "int" ? 1.0 : 1e-6 * std::max(1.0, std::abs(spec.max));
    EXPECT_NO_THROW(load(spec.max)) << spec.name;
    EXPECT_THROW(load(spec.max + step), core::InvalidInput) << spec.name;
    if (spec.min_exclusive) {
      EXPECT_THROW(load(spec.min), core::InvalidInput) << spec.name;
    } else {
      EXPECT_NO_THROW(load(spec.min)) << spec.name;
      EXPECT_THROW(load(spec.min - step), core::InvalidInput) << spec.name;
    }
    try {
      load(spec.max + step);
    } catch (const core::InvalidInput& error) {
      EXPECT_NE(std::string(error.what()).find(spec.name), std::string::npos) << error.what();
    }
  }
  // knot_interval 1e10 once overflowed the knot loop into an endless allocation.
  EXPECT_THROW(DeskewParams::load(TextParams(std::map<std::string, std::string>{{"knot_interval", "1e10"}})),
               core::InvalidInput);
  core::DeskewConfig huge;
  huge.knot_interval = 1e10;
  EXPECT_THROW(huge.validate(), core::InvalidInput);
  // Choices.
  EXPECT_THROW(DeskewParams::load(TextParams(std::map<std::string, std::string>{{"reference", "begin"}})),
               core::InvalidInput);
  EXPECT_THROW(
      DeskewParams::load(TextParams(std::map<std::string, std::string>{{"on_tf_failure", "ignore"}})),
      core::InvalidInput);
  EXPECT_EQ(DeskewParams::load(TextParams(std::map<std::string, std::string>{{"reference", "middle"}}))
                .deskew.reference,
            core::Reference::kMiddle);
  // Frames are normalised.
  EXPECT_EQ(DeskewParams::load(TextParams(std::map<std::string, std::string>{{"fixed_frame", "/odom"}}))
                .fixed_frame,
            "odom");
}

// A misspelled parameter is named, with the one meant.
TEST(Params, UnknownNamesAreNamedWithTheClosestParameter) {
  EXPECT_EQ(DeskewParams::unknownNames({"tf_timout", "tf_timeout", "colour", "stampat", "smoothing_window"}),
            (std::vector<std::string>{"tf_timout (did you mean tf_timeout?)", "colour",
                                      "stampat (did you mean stamp_at?)",
                                      "smoothing_window (no longer used: noisy odometry is averaged over the "
                                      "sweep only)"}));
}

// The live-only parameters are the ones deskew_bag refuses.
TEST(Params, LiveOnlyParameters) {
  const auto& live = DeskewParams::liveOnlyNames();
  EXPECT_EQ(live, (std::vector<std::string>{"max_extrapolation", "input_queue_size", "diagnostics_period"}));
}

}  // namespace
}  // namespace lidar_deskew::ros_adapter
