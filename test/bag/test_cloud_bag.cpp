// Simulated multi-line bags read back with the rosbag C++ API, per driver convention: the layout
// (fields, types, offsets, point step, shape), per-point times decoded against the simulator's true
// times, header stamps and record times as the drivers set them, 3D tf, the truth file, and scoring a
// decoded cloud against the world with the truth's poses.
#include <geometry_msgs/TransformStamped.h>
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include "lidar_deskew/sim/cloud_bag.h"

namespace lidar_deskew::sim {
namespace {

using sensor_msgs::PointField;
constexpr double kMm = 1e-3;

/// The layouts as the drivers publish them, stated here again (not taken from cloud_bag.cpp).
struct ExpectedField {
  std::string name;
  std::uint32_t offset;
  std::uint8_t datatype;
};
struct ExpectedLayout {
  std::vector<ExpectedField> fields;  // after x, y, z float32 at 0, 4, 8
  std::uint32_t point_step;
  std::string time_field;
};

ExpectedLayout expectedLayout(CloudConvention convention) {
  using F = PointField;
  switch (convention) {
    case CloudConvention::kOuster:
      return {{{"intensity", 16, F::FLOAT32},
               {"t", 20, F::UINT32},
               {"reflectivity", 24, F::UINT16},
               {"ring", 26, F::UINT16},
               {"ambient", 28, F::UINT16},
               {"range", 32, F::UINT32}},
              48,
              "t"};
    case CloudConvention::kVelodyneFirst:
    case CloudConvention::kVelodyneLast:
      return {{{"intensity", 12, F::FLOAT32}, {"ring", 16, F::UINT16}, {"time", 18, F::FLOAT32}}, 22, "time"};
    case CloudConvention::kHesai:
      return {{{"intensity", 16, F::FLOAT32}, {"timestamp", 24, F::FLOAT64}, {"ring", 32, F::UINT16}},
              48,
              "timestamp"};
    case CloudConvention::kRoboSense:
      return {{{"intensity", 16, F::FLOAT32}, {"ring", 20, F::UINT16}, {"timestamp", 24, F::FLOAT64}},
              32,
              "timestamp"};
    case CloudConvention::kLivox2:
      return {{{"intensity", 12, F::FLOAT32},
               {"tag", 16, F::UINT8},
               {"line", 17, F::UINT8},
               {"timestamp", 18, F::FLOAT64}},
              26,
              "timestamp"};
    case CloudConvention::kAutoware:
      return {{{"intensity", 12, F::FLOAT32}, {"ring", 16, F::UINT16}, {"time_stamp", 20, F::UINT32}},
              24,
              "time_stamp"};
    case CloudConvention::kLivoxCustom:
      return {{{"reflectivity", 12, F::FLOAT32},
               {"tag", 16, F::UINT8},
               {"line", 17, F::UINT8},
               {"offset_time", 20, F::UINT32}},
              24,
              "offset_time"};
    case CloudConvention::kLaserGeometry:
      return {{{"intensity", 12, F::FLOAT32}, {"stamps", 16, F::FLOAT32}}, 20, "stamps"};
    case CloudConvention::kNoTime:  // velodyne_pointcloud's PointXYZIR: x y z, padding, intensity, ring
      return {{{"intensity", 16, F::FLOAT32}, {"ring", 20, F::UINT16}}, 32, ""};
  }
  return {};
}

template <typename T>
T read(const sensor_msgs::PointCloud2& cloud, std::size_t point, std::uint32_t offset) {
  T value;
  std::memcpy(&value, cloud.data.data() + point * cloud.point_step + offset, sizeof(T));
  return value;
}

/// A point's time [s] on the simulation clock (t = 0 at `epoch`), decoded as a user of the driver
/// would, and how far from the truth that decoding may be by the field's own precision [s].
struct Decoded {
  double time;
  double precision;
};
Decoded decodeTime(const sensor_msgs::PointCloud2& cloud, std::size_t point, CloudConvention convention,
                   core::TimeNs epoch) {
  const double stamp = core::nsToSeconds(static_cast<core::TimeNs>(cloud.header.stamp.toNSec()) - epoch);
  switch (convention) {
    case CloudConvention::kOuster:
      return {stamp + read<std::uint32_t>(cloud, point, 20) * 1e-9, 1e-9};
    case CloudConvention::kAutoware:
      return {stamp + read<std::uint32_t>(cloud, point, 20) * 1e-9, 1e-9};
    case CloudConvention::kLivoxCustom:
      return {stamp + read<std::uint32_t>(cloud, point, 20) * 1e-9, 1e-9};
    case CloudConvention::kVelodyneFirst:
    case CloudConvention::kVelodyneLast: {
      const float relative = read<float>(cloud, point, 18);
      return {stamp + relative, std::abs(relative) * 0x1p-24 + 1e-9};
    }
    case CloudConvention::kLaserGeometry: {
      const float relative = read<float>(cloud, point, 16);
      return {stamp + relative, std::abs(relative) * 0x1p-24 + 1e-9};
    }
    case CloudConvention::kHesai:
    case CloudConvention::kRoboSense: {  // absolute [s]: a double holds 0.24 us at 1.7e9 s
      const double absolute = read<double>(cloud, point, 24);
      return {absolute - core::nsToSeconds(epoch), 0.5e-6};
    }
    case CloudConvention::kLivox2:  // absolute [ns]: a double holds 256 ns at 1.7e18 ns
      return {(read<double>(cloud, point, 18) - static_cast<double>(epoch)) * 1e-9, 0.5e-6};
    case CloudConvention::kNoTime:
      break;  // nothing to decode (not among allCloudConventions())
  }
  return {0.0, 0.0};
}

int ringOf(const sensor_msgs::PointCloud2& cloud, std::size_t point, CloudConvention convention) {
  for (const ExpectedField& field : expectedLayout(convention).fields) {
    if (field.name == "ring")
      return read<std::uint16_t>(cloud, point, field.offset);
    if (field.name == "line")
      return read<std::uint8_t>(cloud, point, field.offset);
  }
  return -1;  // laser_geometry carries no ring
}

struct RecordedBag {
  std::vector<sensor_msgs::PointCloud2> clouds;
  std::vector<core::TimeNs> cloud_record_times;
  std::vector<geometry_msgs::TransformStamped> tf, tf_static;
  bool tf_static_latched = false;  // its connection header says "latching: 1", as rosbag record's
};

RecordedBag readBag(const std::string& path) {
  RecordedBag recorded;
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& message : rosbag::View(bag)) {
    if (auto cloud = message.instantiate<sensor_msgs::PointCloud2>()) {
      EXPECT_EQ(message.getTopic(), "/points");
      recorded.clouds.push_back(*cloud);
      recorded.cloud_record_times.push_back(static_cast<core::TimeNs>(message.getTime().toNSec()));
    } else if (auto transforms = message.instantiate<tf2_msgs::TFMessage>()) {
      auto& into = message.getTopic() == "/tf_static" ? recorded.tf_static : recorded.tf;
      if (message.getTopic() == "/tf_static" && message.getConnectionHeader()) {
        const auto latching = message.getConnectionHeader()->find("latching");
        recorded.tf_static_latched =
            latching != message.getConnectionHeader()->end() && latching->second == "1";
      }
      into.insert(into.end(), transforms->transforms.begin(), transforms->transforms.end());
    } else {
      ADD_FAILURE() << "unexpected message on " << message.getTopic();
    }
  }
  return recorded;
}

Pose3 toPose(const geometry_msgs::Transform& transform) {
  Pose3 pose;
  pose.position = {transform.translation.x, transform.translation.y, transform.translation.z};
  pose.rotation = Eigen::Quaterniond(transform.rotation.w, transform.rotation.x, transform.rotation.y,
                                     transform.rotation.z)
                      .toRotationMatrix();
  return pose;
}

class CloudBagTest : public ::testing::TestWithParam<CloudConvention> {};

TEST_P(CloudBagTest, ReadsBackAsTheDriverWroteIt) {
  const CloudConvention convention = GetParam();
  const std::string name = cloudConventionName(convention);
  // The organized layout with the organized sensor, the dense ones with the VLP-16; rough ground.
  const CloudScenario scenario =
      findCloudScenario(isOrganized(convention) ? "OS1-64/rough/arc" : "VLP16/rough/arc");
  CloudBagOptions options;
  options.convention = convention;
  options.duration = 0.3;  // 3 sweeps
  const std::string bag_path = ::testing::TempDir() + "/cloud_" + name + ".bag";
  const std::string truth_path = ::testing::TempDir() + "/cloud_" + name + ".truth";
  writeCloudBag(scenario, options, bag_path, truth_path);
  const RecordedBag recorded = readBag(bag_path);
  const core::TimeNs epoch = options.epoch;
  const auto bagTime = [&](double t) { return epoch + core::secondsToNs(t); };

  // The same sweeps, simulated again here.
  SpinningLidarModel model = scenario.lidar;
  model.organized = isOrganized(convention);
  const auto trajectory = scenario.trajectory();
  const World3 hall = World3::hall();
  ASSERT_EQ(recorded.clouds.size(), 3u);
  const ExpectedLayout layout = expectedLayout(convention);
  EXPECT_EQ(cloudTimeField(convention), layout.time_field);
  double worst_time_error = 0.0;
  for (std::size_t k = 0; k < recorded.clouds.size(); ++k) {
    const sensor_msgs::PointCloud2& cloud = recorded.clouds[k];
    const SimulatedCloud truth = simulateSweep(hall, *trajectory, scenario.mount, model, 0.1 * k);
    // Layout.
    ASSERT_EQ(cloud.fields.size(), 3 + layout.fields.size()) << name;
    for (std::size_t f = 0; f < cloud.fields.size(); ++f) {
      const ExpectedField expected =
          f < 3 ? ExpectedField{std::string(1, "xyz"[f]), static_cast<std::uint32_t>(4 * f),
                                PointField::FLOAT32}
                : layout.fields[f - 3];
      EXPECT_EQ(cloud.fields[f].name, expected.name) << name;
      EXPECT_EQ(cloud.fields[f].offset, expected.offset) << name << " " << expected.name;
      EXPECT_EQ(cloud.fields[f].datatype, expected.datatype) << name << " " << expected.name;
      EXPECT_EQ(cloud.fields[f].count, 1u);
    }
    EXPECT_EQ(cloud.point_step, layout.point_step) << name;
    EXPECT_EQ(cloud.header.frame_id, "lidar");
    EXPECT_EQ(cloud.header.seq, k);
    EXPECT_FALSE(cloud.is_bigendian);
    if (isOrganized(convention)) {
      EXPECT_EQ(cloud.height, 64u);
      EXPECT_EQ(cloud.width, 1024u);
    } else {
      EXPECT_EQ(cloud.height, 1u);
      EXPECT_EQ(cloud.width, 16u * 1800u);  // the hall is closed: every ray returns
    }
    EXPECT_EQ(cloud.row_step, cloud.width * cloud.point_step);
    ASSERT_EQ(cloud.data.size(), static_cast<std::size_t>(cloud.row_step) * cloud.height);
    ASSERT_EQ(truth.points.size(), static_cast<std::size_t>(cloud.width) * cloud.height);

    // header.stamp as the driver sets it; recorded at the last point + 5 ms.
    double stamp_time = truth.points.front().time;  // first point
    if (convention == CloudConvention::kOuster)
      stamp_time = 0.1 * k;  // sweep start
    if (convention == CloudConvention::kVelodyneLast || convention == CloudConvention::kRoboSense)
      stamp_time = truth.points.back().time;
    // On whole nanoseconds: rounded down at the start or first point, up at the last.
    const double stamp_error =
        core::nsToSeconds(static_cast<core::TimeNs>(cloud.header.stamp.toNSec()) - epoch) - stamp_time;
    EXPECT_LT(std::abs(stamp_error), 1e-9) << name;
    EXPECT_EQ(stamp_error >= 0.0, convention == CloudConvention::kVelodyneLast ||
                                      convention == CloudConvention::kRoboSense || stamp_error == 0.0)
        << name;
    EXPECT_EQ(recorded.cloud_record_times[k], bagTime(truth.end_time + 0.005)) << name;

    // Every point: coordinates, ring, time.
    for (std::size_t i = 0; i < truth.points.size(); ++i) {
      const SimulatedPoint& point = truth.points[i];
      ASSERT_EQ(read<float>(cloud, i, 0), static_cast<float>(point.position.x())) << name << " " << i;
      ASSERT_EQ(read<float>(cloud, i, 4), static_cast<float>(point.position.y()));
      ASSERT_EQ(read<float>(cloud, i, 8), static_cast<float>(point.position.z()));
      if (convention != CloudConvention::kLaserGeometry) {
        ASSERT_EQ(ringOf(cloud, i, convention), point.ring) << name;
      }
      const Decoded decoded = decodeTime(cloud, i, convention, epoch);
      const double error = std::abs(decoded.time - point.time);
      ASSERT_LE(error, decoded.precision) << name << " point " << i;
      worst_time_error = std::max(worst_time_error, error);
      if (convention == CloudConvention::kVelodyneLast) {
        ASSERT_LE(read<float>(cloud, i, 18), 0.0f);
      }
      if (convention == CloudConvention::kVelodyneFirst) {
        ASSERT_GE(read<float>(cloud, i, 18), 0.0f);
      }
      if (convention == CloudConvention::kOuster) {
        ASSERT_EQ(read<std::uint32_t>(cloud, i, 32),
                  static_cast<std::uint32_t>(std::llround(point.range * 1e3)));
      }
    }
  }
  EXPECT_LE(worst_time_error, 1e-6) << name;
  std::printf("%-15s point times decode within %.3g us\n", name.c_str(), worst_time_error * 1e6);

  // tf: the mount once on /tf_static; odom -> base_link at 50 Hz, fully 3D, from 0.1 s before the
  // first sweep to 0.1 s after the last one's end.
  ASSERT_EQ(recorded.tf_static.size(), 1u);
  EXPECT_TRUE(recorded.tf_static_latched);
  EXPECT_EQ(recorded.tf_static[0].header.frame_id, "base_link");
  EXPECT_EQ(recorded.tf_static[0].child_frame_id, "lidar");
  const Pose3 mount = toPose(recorded.tf_static[0].transform);
  EXPECT_LT((mount.position - scenario.mount.position).norm(), 1e-15);
  EXPECT_LT((mount.rotation - scenario.mount.rotation).norm(), 1e-12);
  ASSERT_EQ(recorded.tf.size(), 26u);  // 0.5 s at 50 Hz, both ends
  EXPECT_EQ(static_cast<core::TimeNs>(recorded.tf.front().header.stamp.toNSec()), bagTime(-0.1));
  EXPECT_EQ(static_cast<core::TimeNs>(recorded.tf.back().header.stamp.toNSec()), bagTime(0.4));
  double most_z = 0.0, most_tilt = 0.0;
  for (const geometry_msgs::TransformStamped& transform : recorded.tf) {
    EXPECT_EQ(transform.header.frame_id, "odom");
    EXPECT_EQ(transform.child_frame_id, "base_link");
    const double t = core::nsToSeconds(static_cast<core::TimeNs>(transform.header.stamp.toNSec()) - epoch);
    const Pose3 base = toPose(transform.transform), expected = trajectory->pose(t);
    EXPECT_LT((base.position - expected.position).norm(), 1e-9);
    EXPECT_LT((base.rotation - expected.rotation).norm(), 1e-9);
    most_z = std::max(most_z, std::abs(base.position.z()));
    most_tilt = std::max(most_tilt, std::abs(base.rotation(2, 0)) + std::abs(base.rotation(2, 1)));
  }
  EXPECT_GT(most_z, 0.01);     // m
  EXPECT_GT(most_tilt, 0.02);  // roll and pitch
  // The mount from the start of tf on.
  EXPECT_EQ(recorded.tf_static[0].header.stamp, recorded.tf.front().header.stamp);

  // The truth file, and a decoded cloud scored with it: each point placed with the true sensor pose
  // at its decoded time lies on the world (float32 coordinates: micrometres).
  const CloudTruth read_truth = readCloudTruth(truth_path);
  EXPECT_EQ(read_truth.scenario, scenario.name);
  EXPECT_EQ(read_truth.sensor, scenario.lidar.name);
  EXPECT_EQ(read_truth.convention, name);
  EXPECT_EQ(read_truth.epoch, epoch);
  EXPECT_EQ(read_truth.sweep_start_times, (std::vector<double>{0.0, 0.1, 0.2}));
  const World3 world = World3::byName(read_truth.world);
  std::vector<double> distances;
  const sensor_msgs::PointCloud2& last = recorded.clouds.back();
  for (std::size_t i = 0; i < static_cast<std::size_t>(last.width) * last.height; ++i) {
    const Eigen::Vector3d point(read<float>(last, i, 0), read<float>(last, i, 4), read<float>(last, i, 8));
    const Pose3 sensor = read_truth.sensorPoseAt(decodeTime(last, i, convention, epoch).time);
    distances.push_back(world.distanceTo(sensor.apply(point)));
  }
  const ErrorStats stats = errorStats(distances).scaled(1e3);
  std::printf("%-15s decoded cloud on the true surfaces: %.4f mm RMS, %.4f mm max\n", name.c_str(), stats.rms,
              stats.max);
  EXPECT_LT(stats.max, 0.02);  // mm
  std::remove(bag_path.c_str());
  std::remove(truth_path.c_str());
}

INSTANTIATE_TEST_SUITE_P(AllConventions, CloudBagTest, ::testing::ValuesIn(allCloudConventions()),
                         [](const ::testing::TestParamInfo<CloudConvention>& param) {
                           std::string name = cloudConventionName(param.param);
                           name.erase(std::remove(name.begin(), name.end(), '_'), name.end());
                           return name;
                         });

TEST(CloudBag, ConventionNamesRoundTrip) {
  EXPECT_EQ(allCloudConventions().size(), 9u);  // the ones with a time field
  for (const CloudConvention convention : allCloudConventions())
    EXPECT_EQ(cloudConventionFromName(cloudConventionName(convention)), convention);
  EXPECT_EQ(cloudConventionFromName("no_time"), CloudConvention::kNoTime);
  const std::vector<std::string> names = cloudConventionNames();
  ASSERT_EQ(names.size(), 10u);
  EXPECT_EQ(names.front(), "ouster");
  EXPECT_EQ(names.back(), "no_time");
  EXPECT_THROW(cloudConventionFromName("velodyne"), std::invalid_argument);
  EXPECT_THROW(cloudTimeField(CloudConvention::kNoTime), std::invalid_argument);
}

// The layout without a time field: x y z float32, intensity and ring as velodyne_pointcloud's PointXYZIR
// (32 B, padded), dense in firing order, stamped at the first point.
TEST(CloudBag, NoTimeConventionHasNoTimeField) {
  const CloudScenario scenario = findCloudScenario("VLP16/rough/arc");
  const SimulatedCloud sweep =
      simulateSweep(World3::hall(), *scenario.trajectory(), scenario.mount, scenario.lidar, 0.25);
  const core::TimeNs epoch = 1'700'000'000'000'000'000;
  const sensor_msgs::PointCloud2 cloud = toPointCloud2(sweep, CloudConvention::kNoTime, epoch, "lidar");
  const ExpectedLayout layout = expectedLayout(CloudConvention::kNoTime);
  ASSERT_EQ(cloud.fields.size(), 5u);
  for (std::size_t f = 3; f < cloud.fields.size(); ++f) {
    EXPECT_EQ(cloud.fields[f].name, layout.fields[f - 3].name);
    EXPECT_EQ(cloud.fields[f].offset, layout.fields[f - 3].offset);
    EXPECT_EQ(cloud.fields[f].datatype, layout.fields[f - 3].datatype);
  }
  EXPECT_EQ(cloud.point_step, 32u);
  EXPECT_EQ(cloud.height, 1u);
  ASSERT_EQ(cloud.width, sweep.points.size());
  EXPECT_EQ(static_cast<core::TimeNs>(cloud.header.stamp.toNSec()), epoch + 250'000'000);  // first point
  for (std::size_t i = 0; i < sweep.points.size(); i += 97) {
    EXPECT_EQ(read<float>(cloud, i, 0), static_cast<float>(sweep.points[i].position.x()));
    EXPECT_EQ(read<float>(cloud, i, 8), static_cast<float>(sweep.points[i].position.z()));
    EXPECT_EQ(read<float>(cloud, i, 16), 100.0f);
    EXPECT_EQ(read<std::uint16_t>(cloud, i, 20), sweep.points[i].ring);
  }
}

TEST(CloudBag, OrganizedCloudKeepsNoReturnsAsZeros) {
  // On an endless floor alone the upward rings of the OS1-64 see nothing: zeros, with t and ring set.
  World3 floor;
  floor.addHorizontal({{-1e4, -1e4}, {1e4, -1e4}, {1e4, 1e4}, {-1e4, 1e4}}, 0.0);
  const PlanarTrajectory3 standing(
      std::make_shared<PiecewiseTrajectory>(Pose2{0.0, 0.0, 0.0}, std::vector<MotionPiece>{{1.0}}));
  const SimulatedCloud sweep = simulateSweep(floor, standing, Pose3::fromXyzRpy(0, 0, 0.5, 0, 0, 0),
                                             SpinningLidarModel::os1_64(), 0.0);
  const sensor_msgs::PointCloud2 cloud = toPointCloud2(sweep, CloudConvention::kOuster, 0, "lidar");
  const std::size_t up = 10 * 1024 + 7;  // ring 10 (12 deg up), column 7
  EXPECT_EQ(read<float>(cloud, up, 0), 0.0f);
  EXPECT_EQ(read<float>(cloud, up, 16), 0.0f);         // intensity
  EXPECT_EQ(read<std::uint32_t>(cloud, up, 32), 0u);   // range
  EXPECT_EQ(read<std::uint16_t>(cloud, up, 26), 10u);  // ring
  EXPECT_EQ(read<std::uint32_t>(cloud, up, 20),
            static_cast<std::uint32_t>(std::llround(7 * 1e9 / 10240)));  // t [ns]
  const std::size_t down = 50 * 1024 + 7;
  EXPECT_GT(read<std::uint32_t>(cloud, down, 32), 1000u);
  // A dense convention refuses an organized sweep (and the other way round).
  EXPECT_THROW(toPointCloud2(sweep, CloudConvention::kVelodyneFirst, 0, "lidar"), std::invalid_argument);
}

TEST(CloudBag, TwentyOs1SweepsAreQuickToWrite) {
  CloudBagOptions options;
  options.duration = 2.0;
  options.noise = true;
  const std::string bag_path = ::testing::TempDir() + "/cloud_speed.bag";
  const std::string truth_path = ::testing::TempDir() + "/cloud_speed.truth";
  const auto begin = std::chrono::steady_clock::now();
  writeCloudBag(findCloudScenario("OS1-64/normal/arc"), options, bag_path, truth_path);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  const RecordedBag recorded = readBag(bag_path);
  EXPECT_EQ(recorded.clouds.size(), 20u);
  std::printf("20 OS1-64 sweeps (%d points) written in %.2f s\n", 20 * 65536, seconds);
  EXPECT_LT(seconds, 10.0);
  // Noise on: ranges move by sigma along the beam (not a bit-for-bit copy of the exact sweep).
  const sensor_msgs::PointCloud2& cloud = recorded.clouds[3];
  const SimulatedCloud exact =
      simulateSweep(World3::hall(), *findCloudScenario("OS1-64/normal/arc").trajectory(),
                    findCloudScenario("OS1-64/normal/arc").mount, SpinningLidarModel::os1_64(), 0.3);
  std::vector<double> range_errors;
  for (std::size_t i = 0; i < exact.points.size(); ++i)
    range_errors.push_back(read<std::uint32_t>(cloud, i, 32) * kMm - exact.points[i].range);
  EXPECT_NEAR(errorStats(range_errors).rms, 0.03, 0.003);
  std::remove(bag_path.c_str());
  std::remove(truth_path.c_str());
}

}  // namespace
}  // namespace lidar_deskew::sim
