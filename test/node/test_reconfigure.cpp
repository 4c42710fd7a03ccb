// dynamic_reconfigure on the live nodes (reconfigure.test): the generated descriptions
// (cfg/DeskewScan.cfg, cfg/DeskewCloud.cfg) agree with the parameter table, and each running node offers
// only the parameters its input reads; changes made through the real service while scans flow take
// effect (a wrong stamp_at put right live, on_tf_failure switched), and a change the node cannot take is
// refused whole with the values in force sent back to the client.
#include <dynamic_reconfigure/ConfigDescription.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <gtest/gtest.h>
#include <ros/topic.h>
#include <rosgraph_msgs/Log.h>

#include <algorithm>
#include <set>

#include "lidar_deskew/node/config_params.h"
#include "lidar_deskew/ros/deskew_params.h"
#include "lidar_deskew/ros/text_params.h"
#include "live_rig.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::DeskewParams;
using ros_adapter::Input;
using ros_adapter::ParamSpec;

/// [s] Outputs are stamped on whole microseconds, and an end stamp gives the start through float
/// time_increment: the output of a scan is found within this of its expected stamp.
constexpr double kStampTolerance = 20e-6;

/// Every reconfigurable parameter of the table that the node of `input` reads is in its generated config
/// with the table's type, default, bounds and choices; nothing else is.
template <class Config>
void expectDescriptionMatchesTheTable(Input input) {
  std::set<std::string> described;
  for (const auto& description : Config::__getParamDescriptions__())
    described.insert(description->name);
  const std::vector<std::string> names = DeskewParams::reconfigurableNames(input);
  EXPECT_EQ(described, std::set<std::string>(names.begin(), names.end()));
  const DeskewParams defaults = DeskewParams::load(node::ConfigParams(Config::__getDefault__()));
  const DeskewParams table;
  EXPECT_EQ(defaults.deskew.reference, table.deskew.reference);
  EXPECT_EQ(defaults.tf_timeout, table.tf_timeout);
  EXPECT_EQ(defaults.diagnostics_period, table.diagnostics_period);
  for (const ParamSpec& spec : DeskewParams::specs()) {
    if (!spec.reconfigurable || !spec.readBy(input))
      continue;
    SCOPED_TRACE(spec.name);
    const node::ConfigParams dflt(Config::__getDefault__());
    const node::ConfigParams min(Config::__getMin__());
    const node::ConfigParams max(Config::__getMax__());
    const std::string type = spec.type;
    if (type == "double") {
      double value = 0.0, low = 0.0, high = 0.0;
      ASSERT_TRUE(dflt.get(spec.name, value) && min.get(spec.name, low) && max.get(spec.name, high));
      EXPECT_EQ(value, std::stod(spec.default_value));
      EXPECT_EQ(high, spec.max);
      // An exclusive minimum: the slider starts just above it.
      if (spec.min_exclusive) {
        EXPECT_GT(low, spec.min);
        EXPECT_LT(low, value);
      } else {
        EXPECT_EQ(low, spec.min);
      }
    } else if (type == "int") {
      int value = 0, low = 0, high = 0;
      ASSERT_TRUE(dflt.get(spec.name, value) && min.get(spec.name, low) && max.get(spec.name, high));
      EXPECT_EQ(value, std::stoi(spec.default_value));
      EXPECT_EQ(low, spec.min);
      EXPECT_EQ(high, spec.max);
    } else if (type == "bool") {
      bool value = true;
      ASSERT_TRUE(dflt.get(spec.name, value));
      EXPECT_EQ(value, std::string(spec.default_value) == "true");
    } else {
      ASSERT_EQ(type, "string");
      std::string value;
      ASSERT_TRUE(dflt.get(spec.name, value));
      EXPECT_EQ(value, spec.default_value);
      // The enum offers exactly the table's choices.
      std::string edit_method;
      for (const auto& description : Config::__getParamDescriptions__()) {
        if (description->name == spec.name)
          edit_method = description->edit_method;
      }
      std::string choices = spec.choices;
      std::size_t offered = 0;
      for (std::size_t at = edit_method.find("'value': '"); at != std::string::npos;
           at = edit_method.find("'value': '", at + 1)) {
        const std::size_t begin = at + 10;
        const std::string choice = edit_method.substr(begin, edit_method.find('\'', begin) - begin);
        EXPECT_NE(("|" + choices + "|").find("|" + choice + "|"), std::string::npos) << choice;
        ++offered;
      }
      EXPECT_EQ(offered, static_cast<std::size_t>(std::count(choices.begin(), choices.end(), '|') + 1));
    }
  }
}

TEST(Reconfigure, DescriptionsMatchTheParameterTable) {
  {
    SCOPED_TRACE("DeskewScanConfig");
    expectDescriptionMatchesTheTable<DeskewScanConfig>(Input::kScans);
    EXPECT_EQ(DeskewParams::load(node::ConfigParams(DeskewScanConfig::__getDefault__())).timing.stamp_at,
              DeskewParams().timing.stamp_at);
  }
  {
    SCOPED_TRACE("DeskewCloudConfig");
    expectDescriptionMatchesTheTable<DeskewCloudConfig>(Input::kClouds);
  }
}

/// The parameter names a running node's dynamic_reconfigure offers (its latched parameter_descriptions,
/// which rqt_reconfigure and dynparam read).
std::set<std::string> offeredBy(const std::string& node) {
  const auto description = ros::topic::waitForMessage<dynamic_reconfigure::ConfigDescription>(
      node + "/parameter_descriptions", ros::Duration(10.0));
  std::set<std::string> names;
  if (!description) {
    ADD_FAILURE() << "no description from " << node;
    return names;
  }
  for (const auto& group : description->groups) {
    for (const auto& parameter : group.parameters)
      names.insert(parameter.name);
  }
  return names;
}

// Each running node offers only the parameters its input reads: the LaserScan node no planar-scan band
// of clouds, the cloud node no beam timing or re-binning of scans.
TEST(Reconfigure, EachNodeOffersOnlyItsOwnParameters) {
  const std::set<std::string> scan_node = offeredBy("/lidar_deskew");
  const std::set<std::string> cloud_node = offeredBy("/lidar_deskew_cloud");
  for (const std::string cloud_only : {"scan_height_min", "scan_height_max", "scan_angle_min",
                                       "scan_angle_max", "scan_angle_increment", "scan_range_max"}) {
    EXPECT_EQ(scan_node.count(cloud_only), 0u) << cloud_only;
    EXPECT_EQ(cloud_node.count(cloud_only), 1u) << cloud_only;
  }
  for (const std::string scan_only :
       {"stamp_at", "beam_order", "scan_period", "use_scan_period", "rebin_min_gap", "rebin_gap_factor"}) {
    EXPECT_EQ(scan_node.count(scan_only), 1u) << scan_only;
    EXPECT_EQ(cloud_node.count(scan_only), 0u) << scan_only;
  }
  for (const std::string both : {"reference", "time_offset", "tf_timeout", "on_tf_failure", "queue_size"}) {
    EXPECT_EQ(scan_node.count(both), 1u) << both;
    EXPECT_EQ(cloud_node.count(both), 1u) << both;
  }
  const std::vector<std::string> scans = DeskewParams::reconfigurableNames(Input::kScans);
  const std::vector<std::string> clouds = DeskewParams::reconfigurableNames(Input::kClouds);
  EXPECT_EQ(scan_node, std::set<std::string>(scans.begin(), scans.end()));
  EXPECT_EQ(cloud_node, std::set<std::string>(clouds.begin(), clouds.end()));
}

/// Sets parameters through the node's real service; returns the config the node sends back.
dynamic_reconfigure::Config reconfigure(const std::map<std::string, std::string>& strings,
                                        const std::map<std::string, double>& doubles) {
  dynamic_reconfigure::Reconfigure call;
  for (const auto& [name, value] : strings) {
    dynamic_reconfigure::StrParameter parameter;
    parameter.name = name;
    parameter.value = value;
    call.request.config.strs.push_back(parameter);
  }
  for (const auto& [name, value] : doubles) {
    dynamic_reconfigure::DoubleParameter parameter;
    parameter.name = name;
    parameter.value = value;
    call.request.config.doubles.push_back(parameter);
  }
  EXPECT_TRUE(ros::service::waitForService("/lidar_deskew/set_parameters", 10000));
  EXPECT_TRUE(ros::service::call("/lidar_deskew/set_parameters", call));
  return call.response.config;
}

std::string stringIn(const dynamic_reconfigure::Config& config, const std::string& name) {
  for (const auto& parameter : config.strs) {
    if (parameter.name == name)
      return parameter.value;
  }
  return "";
}

double doubleIn(const dynamic_reconfigure::Config& config, const std::string& name) {
  for (const auto& parameter : config.doubles) {
    if (parameter.name == name)
      return parameter.value;
  }
  return -1.0;
}

TEST(Reconfigure, ChangesTakeEffectWhileScansFlow) {
  // The node's log, as rqt_console shows it: each refusal is logged once, with its reason.
  std::vector<std::string> refusals;
  ros::NodeHandle nh;
  const ros::Subscriber log =
      nh.subscribe<rosgraph_msgs::Log>("/rosout", 100, [&](const rosgraph_msgs::Log::ConstPtr& line) {
        if (line->name == "/lidar_deskew" && line->msg.find("refused") != std::string::npos)
          refusals.push_back(line->msg);
      });
  LiveRig rig;
  ASSERT_TRUE(rig.connect());
  const double sweep = (rig.model.beams - 1) * rig.model.timeIncrement();  // first to last beam [s]
  // The driver stamps the end of the sweep; the node starts with the default stamp_at: start.
  const auto stamped_at_end = [&](double t) {
    return [&, t](sensor_msgs::LaserScan& scan) { scan.header.stamp = rig.stampOf(t + sweep); };
  };
  sensor_msgs::LaserScan::ConstPtr scan;
  sensor_msgs::PointCloud2::ConstPtr cloud;
  rig.publishTfUntil(0.1);
  rig.publishScan(0.1, stamped_at_end(0.1));
  rig.publishTfUntil(0.1 + 2 * sweep + 0.04);
  ASSERT_TRUE(
      rig.waitForOutputs(rig.stampOf(0.1 + sweep), 5.0, scan, cloud, kStampTolerance));  // taken as the start
  const double wrong = rms(cloudDistances(rig, *cloud));

  const dynamic_reconfigure::Config taken = reconfigure({{"stamp_at", "end"}}, {});
  EXPECT_EQ(stringIn(taken, "stamp_at"), "end");
  rig.publishTfUntil(0.3);
  rig.publishScan(0.3, stamped_at_end(0.3));
  rig.publishTfUntil(0.3 + sweep + 0.04);
  ASSERT_TRUE(rig.waitForOutputs(rig.stampOf(0.3), 5.0, scan, cloud,
                                 kStampTolerance));  // the reference: the first beam
  const double right = rms(cloudDistances(rig, *cloud));
  std::printf("stamp_at start on end-stamped scans: %.1f mm RMS; after stamp_at:=end live: %.2f mm\n",
              1e3 * wrong, 1e3 * right);
  EXPECT_GT(wrong, 10e-3);
  EXPECT_LT(right, 2e-3);

  // A tf_timeout longer than the tf cache holds cannot be taken while running: refused, the running
  // value sent back.
  const dynamic_reconfigure::Config refused = reconfigure({}, {{"tf_timeout", 30.0}});
  EXPECT_DOUBLE_EQ(doubleIn(refused, "tf_timeout"), 0.2);
  // A value outside the choices (the service takes any string): the value in force comes back, and is
  // what the parameter server holds (`dynparam get`).
  EXPECT_EQ(stringIn(reconfigure({{"stamp_at", "middle"}}, {}), "stamp_at"), "end");
  std::string on_server;
  EXPECT_TRUE(ros::param::get("/lidar_deskew/stamp_at", on_server));
  EXPECT_EQ(on_server, "end");
  // A change is taken whole or not at all: with a refused tf_timeout, a valid stamp_at comes back too.
  const dynamic_reconfigure::Config both = reconfigure({{"stamp_at", "start"}}, {{"tf_timeout", 30.0}});
  EXPECT_EQ(stringIn(both, "stamp_at"), "end");
  EXPECT_DOUBLE_EQ(doubleIn(both, "tf_timeout"), 0.2);
  // A parameter this node does not offer (the clouds' band) is not taken, nor sent back.
  const dynamic_reconfigure::Config foreign = reconfigure({}, {{"scan_height_min", -0.5}});
  for (const auto& parameter : foreign.doubles)
    EXPECT_NE(parameter.name, "scan_height_min");
  EXPECT_EQ(stringIn(foreign, "stamp_at"), "end");
  // Three refusals, three lines; the one of stamp_at names the value and the choices.
  rig.waitFor([&] { return refusals.size() >= 3; }, 5.0);
  rig.spinFor(0.5);
  ASSERT_EQ(refusals.size(), 3u);
  EXPECT_NE(refusals[0].find("tf_timeout: must be at most"), std::string::npos) << refusals[0];
  EXPECT_NE(refusals[1].find("stamp_at: must be one of start|end, got 'middle'"), std::string::npos)
      << refusals[1];

  // on_tf_failure: a scan whose tf never comes is dropped, then, switched live, passed through.
  rig.publishScan(0.6, stamped_at_end(0.6));
  ASSERT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("dropped: tf") >= 1.0; }, 5.0));
  EXPECT_EQ(rig.diagnosticNumber("passed through"), 0.0);
  reconfigure({{"on_tf_failure", "pass_through"}}, {});
  rig.publishScan(0.7, stamped_at_end(0.7));
  // Passed through: the input scan itself comes out (its own stamp), counted so.
  EXPECT_TRUE(rig.waitFor([&] { return rig.diagnosticNumber("passed through") >= 1.0; }, 5.0));
  EXPECT_EQ(rig.outputCount(rig.stampOf(0.7 + sweep) - ros::Duration(1e-6), rig.stampOf(0.7 + sweep)), 1u);
  EXPECT_EQ(rig.outputCount(rig.stampOf(0.6), rig.stampOf(0.6 + sweep)), 0u);  // the dropped one
}

}  // namespace
}  // namespace lidar_deskew::test

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_reconfigure");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
