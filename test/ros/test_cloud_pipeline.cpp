// CloudPipeline (PointCloud2 in, deskewed PointCloud2 out): the scan pipeline's waiting and failure
// rules with CloudProcessor, fed by hand with real tf2 buffers. The clouds are the simulator's UTM-30LX
// sweeps (6 m/s, 5 rad/s arc) written as drivers write clouds: Ouster's organized layout with zeros
// for no return and uint32 ns offsets, and Velodyne's dense layout stamped at the last packet with
// negative float32 seconds. Truth: the simulator's walls.
#include <gtest/gtest.h>
#include <sensor_msgs/PointField.h>

#include <cstring>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_pipeline.h"
#include "lidar_deskew/sim/sim.h"
#include "support/tf_tree.h"

namespace lidar_deskew::test {
namespace {

using ros_adapter::CloudPipeline;
using ros_adapter::PipelineEvent;
using sensor_msgs::PointField;

constexpr double kTfPeriod = 0.02;

enum class Layout { kOuster, kVelodyneLast };

struct Xy {
  double x, y;
};

PointField field(const std::string& name, std::uint32_t offset, std::uint8_t datatype) {
  PointField f;
  f.name = name;
  f.offset = offset;
  f.datatype = datatype;
  f.count = 1;
  return f;
}

/// The scan as a driver's cloud: x y z float32 at 0, intensity float32 at 12, the time field at 16.
sensor_msgs::PointCloud2::Ptr cloudOf(const sensor_msgs::LaserScan& scan, Layout layout) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header = scan.header;
  const bool ouster = layout == Layout::kOuster;
  cloud->fields = {field("x", 0, PointField::FLOAT32), field("y", 4, PointField::FLOAT32),
                   field("z", 8, PointField::FLOAT32), field("intensity", 12, PointField::FLOAT32),
                   field(ouster ? "t" : "time", 16, ouster ? PointField::UINT32 : PointField::FLOAT32)};
  cloud->point_step = 24;
  const std::size_t n = scan.ranges.size();
  const double last = (n - 1) * static_cast<double>(scan.time_increment);
  if (!ouster)
    cloud->header.stamp = scan.header.stamp + ros::Duration(last);  // the last packet
  std::vector<std::uint8_t> data;
  std::size_t points = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float r = scan.ranges[i];
    const bool hit = std::isfinite(r);
    if (!hit && !ouster)
      continue;  // dense: no-return points left out
    const double angle = scan.angle_min + i * static_cast<double>(scan.angle_increment);
    const float xyz[4] = {hit ? static_cast<float>(r * std::cos(angle)) : 0.0f,
                          hit ? static_cast<float>(r * std::sin(angle)) : 0.0f, 0.0f, 100.0f + i};
    const double offset = i * static_cast<double>(scan.time_increment);
    std::uint8_t point[24] = {};
    std::memcpy(point, xyz, sizeof xyz);
    if (ouster) {
      const auto t = static_cast<std::uint32_t>(std::llround(offset * 1e9));
      std::memcpy(point + 16, &t, sizeof t);
    } else {
      const auto time = static_cast<float>(offset - last);
      std::memcpy(point + 16, &time, sizeof time);
    }
    data.insert(data.end(), point, point + 24);
    ++points;
  }
  cloud->width = static_cast<std::uint32_t>(points);
  cloud->height = 1;
  cloud->row_step = cloud->point_step * cloud->width;
  cloud->data = std::move(data);
  cloud->is_dense = !ouster;
  return cloud;
}

float floatAt(const sensor_msgs::PointCloud2& cloud, std::size_t i, std::uint32_t offset) {
  float value;
  std::memcpy(&value, &cloud.data[i * cloud.point_step + offset], sizeof value);
  return value;
}

/// A cloud pipeline and everything it handed out.
struct CloudRun {
  explicit CloudRun(Layout layout_in, ros_adapter::DeskewParams params = {})
      : layout(layout_in),
        pipeline(
            withFrames(params, drive.tree),
            [this](const CloudPipeline::Result& result) { results.push_back(result); },
            [this](PipelineEvent event, const std::string& text) { events.emplace_back(event, text); }) {}
  static ros_adapter::DeskewParams withFrames(ros_adapter::DeskewParams params, const TfTree& tree) {
    params.fixed_frame = tree.fixed;
    params.base_frame = tree.base;
    return params;
  }
  void tfUntil(double t) {
    for (; tf_until + kTfPeriod <= t + 1e-9; tf_until += kTfPeriod)
      pipeline.addTransforms({drive.motionAt(tf_until + kTfPeriod)}, false, tf_until + kTfPeriod);
  }
  void sweep(double t) {
    inputs.push_back(cloudOf(*drive.scanAt(t), layout));
    pipeline.add(inputs.back(), t + 1.0 / drive.model.rate);
    tfUntil(t + 1.0 / drive.model.rate + kTfPeriod);
  }
  std::vector<Xy> returns(const sensor_msgs::PointCloud2& cloud) const {
    std::vector<Xy> points;
    for (std::size_t i = 0; i < cloud.width; ++i) {
      const float x = floatAt(cloud, i, 0), y = floatAt(cloud, i, 4);
      if (x != 0.0f || y != 0.0f)
        points.push_back({x, y});
    }
    return points;
  }

  Drive drive;
  Layout layout;
  double tf_until = -0.1;
  CloudPipeline pipeline;
  std::vector<sensor_msgs::PointCloud2::Ptr> inputs;
  std::vector<CloudPipeline::Result> results;
  std::vector<std::pair<PipelineEvent, std::string>> events;
};

TEST(CloudPipeline, DriverCloudsAreCorrectedToTheWallsKeepingTheirLayout) {
  for (Layout layout : {Layout::kOuster, Layout::kVelodyneLast}) {
    SCOPED_TRACE(layout == Layout::kOuster ? "Ouster" : "Velodyne, stamped at the last packet");
    CloudRun run(layout);
    run.pipeline.addTransforms(run.drive.statics(), true, 0.0);
    run.tfUntil(0.1);
    for (int k = 0; k < 4; ++k)
      run.sweep(0.1 + k * 0.025);
    ASSERT_EQ(run.results.size(), 4u);
    for (std::size_t k = 0; k < run.results.size(); ++k) {
      const sensor_msgs::PointCloud2& in = *run.inputs[k];
      const sensor_msgs::PointCloud2& out = *run.results[k].outputs.cloud;
      EXPECT_TRUE(run.results[k].corrected);
      // Stamped at the first point (reference start), whatever the header said.
      EXPECT_EQ(out.header.stamp, run.drive.stampOf(0.1 + k * 0.025));
      EXPECT_EQ(out.fields.size(), in.fields.size());
      EXPECT_EQ(out.point_step, in.point_step);
      EXPECT_EQ(out.width, in.width);
      EXPECT_EQ(out.data.size(), in.data.size());
      const std::vector<double> raw =
          run.drive.distances(run.returns(in), run.drive.stampOf(0.1 + k * 0.025));
      const std::vector<double> corrected = run.drive.distances(run.returns(out), out.header.stamp);
      EXPECT_EQ(corrected.size(), raw.size());
      EXPECT_GT(rms(raw), 0.05);
      EXPECT_LT(rms(corrected), 1e-3) << "raw " << rms(raw);
      for (std::size_t i = 0; i < in.width; ++i) {
        EXPECT_EQ(floatAt(out, i, 12), floatAt(in, i, 12));  // intensity untouched
        const bool no_return = floatAt(in, i, 0) == 0.0f && floatAt(in, i, 4) == 0.0f;
        if (no_return) {  // left as it was: zeros, its time kept
          EXPECT_EQ(std::memcmp(&out.data[i * 24], &in.data[i * 24], 24), 0);
        } else if (layout == Layout::kOuster) {
          std::uint32_t t;
          std::memcpy(&t, &out.data[i * 24 + 16], sizeof t);
          EXPECT_EQ(t, 0u);  // the time its corrected position holds
        } else {
          EXPECT_EQ(floatAt(out, i, 16), 0.0f);
        }
      }
    }
  }
}

TEST(CloudPipeline, MissingTfFailsAndPassThroughRepublishesTheInput) {
  ros_adapter::DeskewParams params;
  params.on_tf_failure = ros_adapter::OnTfFailure::kPassThrough;
  CloudRun run(Layout::kOuster, params);
  run.pipeline.addTransforms(run.drive.statics(), true, 0.0);
  run.tfUntil(0.1);
  run.inputs.push_back(cloudOf(*run.drive.scanAt(0.2), Layout::kOuster));
  run.pipeline.add(run.inputs.back(), 0.25);
  run.pipeline.expire(0.25 + params.tf_timeout + 0.01);
  ASSERT_EQ(run.results.size(), 1u);
  EXPECT_FALSE(run.results[0].corrected);
  EXPECT_EQ(run.results[0].outputs.cloud.get(), run.inputs.back().get());
  EXPECT_EQ(run.pipeline.counters().passed_through, 1u);
}

TEST(CloudPipeline, CloudWithoutTimeIsDroppedNamingItsFields) {
  CloudRun run(Layout::kOuster);
  auto cloud = cloudOf(*run.drive.scanAt(0.2), Layout::kOuster);
  cloud->fields.back().name = "ring";
  run.pipeline.add(cloud, 0.25);
  EXPECT_EQ(run.pipeline.counters().dropped_invalid, 1u);
  ASSERT_FALSE(run.events.empty());
  EXPECT_NE(run.events.back().second.find(
                "x (float32), y (float32), z (float32), intensity (float32), ring (uint32)"),
            std::string::npos)
      << run.events.back().second;
}

}  // namespace
}  // namespace lidar_deskew::test
