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
#include "support/temporary.h"

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
  std::vector<core::TimeNs> tf_record_times;  // of each /tf transform
  std::vector<core::TimeNs> record_times;     // of every message, in file order
  bool tf_static_latched = false;             // its connection header says "latching: 1", as rosbag record's
};

RecordedBag readBag(const std::string& path) {
  RecordedBag recorded;
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& message : rosbag::View(bag)) {
    recorded.record_times.push_back(static_cast<core::TimeNs>(message.getTime().toNSec()));
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
      if (message.getTopic() == "/tf") {
        recorded.tf_record_times.insert(recorded.tf_record_times.end(), transforms->transforms.size(),
                                        static_cast<core::TimeNs>(message.getTime().toNSec()));
      }
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
  const std::string bag_path = test::temporary("cloud", name + ".bag");
  const std::string truth_path = test::temporary("cloud", name + ".truth");
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
  const std::string bag_path = test::temporary("cloud", "speed.bag");
  const std::string truth_path = test::temporary("cloud", "speed.truth");
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

// Odometry as robots produce it (CloudBagOptions' odom_*), on 0.3 s of VLP16/rough/arc (1.5 m/s, 2 rad/s
// on rough ground): /tf's planar part (x, y, yaw) is what the wheels report, its z, roll and pitch the
// truth at the sample's true time; the clouds are the same as with perfect odometry; the truth file
// records the odometry.
struct CloudOdometryBag {
  CloudScenario scenario = findCloudScenario("VLP16/rough/arc");
  CloudBagOptions options;
  RecordedBag recorded;
  CloudTruth truth;
  std::vector<Pose2> planar;  // /tf's x, y and yaw
  double seconds(core::TimeNs time) const { return core::nsToSeconds(time - options.epoch); }
  double stamp(std::size_t k) const {
    return seconds(static_cast<core::TimeNs>(recorded.tf[k].header.stamp.toNSec()));
  }
};

CloudOdometryBag writeCloudOdometryBag(double noise, const OdometryTiming& timing, const std::string& label,
                                       unsigned seed = 4) {
  CloudOdometryBag result;
  result.options.convention = CloudConvention::kVelodyneFirst;
  result.options.duration = 0.3;
  result.options.odom_noise = noise;
  result.options.odom_noise_seed = seed;
  result.options.odom_timing = timing;
  const std::string stem = test::temporary("cloud_odom", label);
  writeCloudBag(result.scenario, result.options, stem + ".bag", stem + ".truth");
  result.recorded = readBag(stem + ".bag");
  result.truth = readCloudTruth(stem + ".truth");
  std::remove((stem + ".bag").c_str());
  std::remove((stem + ".truth").c_str());
  for (const geometry_msgs::TransformStamped& transform : result.recorded.tf) {
    const Pose3 pose = toPose(transform.transform);
    result.planar.push_back(
        {pose.position.x(), pose.position.y(), std::atan2(pose.rotation(1, 0), pose.rotation(0, 0))});
  }
  return result;
}

/// Every /tf pose's z and tilt (the rotation's last row: roll and pitch) are the truth's at `true_time(k)`.
template <typename TrueTime>
void expectTrueHeightAndTilt(const CloudOdometryBag& bag, TrueTime true_time, double tolerance) {
  const auto trajectory = bag.scenario.trajectory();
  double most_tilt = 0.0;
  for (std::size_t k = 0; k < bag.recorded.tf.size(); ++k) {
    const Pose3 pose = toPose(bag.recorded.tf[k].transform), truth = trajectory->pose(true_time(k));
    EXPECT_NEAR(pose.position.z(), truth.position.z(), tolerance) << k;
    EXPECT_LT((pose.rotation.row(2) - truth.rotation.row(2)).norm(), tolerance) << k;
    most_tilt = std::max(most_tilt, std::abs(truth.rotation(2, 0)) + std::abs(truth.rotation(2, 1)));
  }
  EXPECT_GT(most_tilt, 0.02);  // rough ground: there is a tilt to keep
}

// 10 % per 20 ms step: x, y and yaw are NoisyOdometry's (same start, steps and seed) at the 50 Hz grid,
// drifting from the truth; z, roll and pitch are true; the clouds are bit for bit the perfect bag's.
TEST(CloudBagOdometry, Noise) {
  const CloudOdometryBag perfect = writeCloudOdometryBag(0.0, {}, "perfect");
  const CloudOdometryBag noisy = writeCloudOdometryBag(0.1, {}, "noise", 9);
  ASSERT_EQ(noisy.recorded.tf.size(), 26u);  // -0.1 .. 0.4 s
  ASSERT_EQ(noisy.recorded.clouds.size(), perfect.recorded.clouds.size());
  for (std::size_t k = 0; k < noisy.recorded.clouds.size(); ++k)
    EXPECT_EQ(noisy.recorded.clouds[k].data, perfect.recorded.clouds[k].data) << k;
  const PiecewiseTrajectory truth(noisy.scenario.start, noisy.scenario.pieces);
  const NoisyOdometry model(truth, -0.1, 0.4, 0.1, 9);
  double drift = 0.0, heading_drift = 0.0;
  for (std::size_t k = 0; k < noisy.planar.size(); ++k) {
    const double t = -0.1 + static_cast<double>(k) / 50.0;
    EXPECT_NEAR(noisy.stamp(k), t, 1e-9) << k;
    const Pose2 expected = model.pose(t), true_pose = truth.pose(t);
    EXPECT_NEAR(noisy.planar[k].x, expected.x, 1e-9) << k;
    EXPECT_NEAR(noisy.planar[k].y, expected.y, 1e-9) << k;
    EXPECT_NEAR(std::remainder(noisy.planar[k].yaw - expected.yaw, 2 * M_PI), 0.0, 1e-9) << k;
    EXPECT_NEAR(perfect.planar[k].x, true_pose.x, 1e-12) << k;
    drift = std::max(drift, std::hypot(noisy.planar[k].x - true_pose.x, noisy.planar[k].y - true_pose.y));
    heading_drift =
        std::max(heading_drift, std::abs(std::remainder(noisy.planar[k].yaw - true_pose.yaw, 2 * M_PI)));
  }
  expectTrueHeightAndTilt(
      noisy, [&](std::size_t k) { return -0.1 + static_cast<double>(k) / 50.0; }, 1e-9);
  std::printf("odometry 10 %% per step on rough ground: drift up to %.1f mm, %.2f deg over 0.5 s\n",
              1e3 * drift, heading_drift * 180 / M_PI);
  EXPECT_GT(drift, 0.001);
  EXPECT_GT(heading_drift, 0.001);
  EXPECT_EQ(noisy.truth.odom_noise, 0.1);
  EXPECT_EQ(noisy.truth.odom_noise_seed, 9u);
  EXPECT_EQ(perfect.truth.odom_noise, 0.0);
  EXPECT_FALSE(perfect.truth.odom_timing.any());
}

// tf_margin: /tf from that long before the first sweep to that long after the last one's end.
TEST(CloudBagOdometry, TfMargin) {
  CloudBagOptions options;
  options.duration = 0.1;
  options.tf_margin = 1.0;
  const std::string stem = test::temporary("cloud_odom", "margin");
  writeCloudBag(findCloudScenario("VLP16/normal/arc"), options, stem + ".bag", stem + ".truth");
  const RecordedBag recorded = readBag(stem + ".bag");
  std::remove((stem + ".bag").c_str());
  std::remove((stem + ".truth").c_str());
  ASSERT_EQ(recorded.tf.size(), 106u);  // -1 .. 1.1 s at 50 Hz
  EXPECT_EQ(static_cast<core::TimeNs>(recorded.tf.front().header.stamp.toNSec()),
            options.epoch - 1'000'000'000);
  EXPECT_EQ(static_cast<core::TimeNs>(recorded.tf.back().header.stamp.toNSec()),
            options.epoch + 1'100'000'000);
  EXPECT_TRUE(std::is_sorted(recorded.record_times.begin(), recorded.record_times.end()));
}

// Stamps jittered by up to 5 ms: one more sample at each end, every pose the full 3D truth at the grid
// time (not at the stamp), the mount stamped at the earliest stamp.
TEST(CloudBagOdometry, StampJitter) {
  OdometryTiming timing;
  timing.jitter = 0.005;
  const CloudOdometryBag bag = writeCloudOdometryBag(0.0, timing, "jitter");
  ASSERT_EQ(bag.recorded.tf.size(), 28u);  // -0.12 .. 0.42 s
  const auto trajectory = bag.scenario.trajectory();
  double largest_error = 0.0, earliest = 1.0;
  for (std::size_t k = 0; k < bag.recorded.tf.size(); ++k) {
    const double t = -0.12 + static_cast<double>(k) / 50.0;
    EXPECT_LE(std::abs(bag.stamp(k) - t), 0.005 + 1e-9) << k;
    largest_error = std::max(largest_error, std::abs(bag.stamp(k) - t));
    earliest = std::min(earliest, bag.stamp(k));
    const Pose3 pose = toPose(bag.recorded.tf[k].transform), truth = trajectory->pose(t);
    EXPECT_LT((pose.position - truth.position).norm(), 1e-12) << k;
    EXPECT_LT((pose.rotation - truth.rotation).norm(), 1e-12) << k;
    EXPECT_EQ(bag.recorded.tf_record_times[k],
              static_cast<core::TimeNs>(bag.recorded.tf[k].header.stamp.toNSec()));
  }
  EXPECT_GT(largest_error, 0.003);
  EXPECT_NEAR(bag.seconds(static_cast<core::TimeNs>(bag.recorded.tf_static[0].header.stamp.toNSec())),
              earliest, 1e-9);
  EXPECT_EQ(bag.truth.odom_timing.jitter, 0.005);
}

// 5 to 11 Hz: every interval in [1/11, 1/5] s, each pose the truth at its stamp, the stamps covering
// every cloud's points.
TEST(CloudBagOdometry, IrregularRate) {
  OdometryTiming timing;
  timing.rate_min = 5.0;
  timing.rate_max = 11.0;
  const CloudOdometryBag bag = writeCloudOdometryBag(0.0, timing, "rate");
  const auto trajectory = bag.scenario.trajectory();
  ASSERT_GE(bag.recorded.tf.size(), 3u);
  for (std::size_t k = 0; k < bag.recorded.tf.size(); ++k) {
    const Pose3 pose = toPose(bag.recorded.tf[k].transform), truth = trajectory->pose(bag.stamp(k));
    EXPECT_LT((pose.position - truth.position).norm(), 1e-6) << k;  // the stamp is the time rounded to 1 ns
    EXPECT_LT((pose.rotation - truth.rotation).norm(), 1e-6) << k;
    if (k > 0) {
      EXPECT_GE(bag.stamp(k) - bag.stamp(k - 1), 1.0 / 11.0 - 2e-9) << k;
      EXPECT_LE(bag.stamp(k) - bag.stamp(k - 1), 1.0 / 5.0 + 2e-9) << k;
    }
  }
  EXPECT_LE(bag.stamp(0), -0.1);
  EXPECT_GE(bag.stamp(bag.recorded.tf.size() - 1), 0.4);
  EXPECT_EQ(bag.truth.odom_timing.rate_min, 5.0);
  EXPECT_EQ(bag.truth.odom_timing.rate_max, 11.0);
}

// Encoders of 1 mm ticks on a 0.235 m wheel base: between samples the planar step is whole ticks (heading
// nr - nl ticks of 1 mm / 0.235 m, arc (nl + nr) / 2 ticks, of one parity), the heading never more than
// two ticks' worth off the truth; z, roll and pitch the truth's.
TEST(CloudBagOdometry, EncoderTicks) {
  OdometryTiming timing;
  timing.tick = 0.001;
  timing.wheel_base = 0.235;  // not 0.3: 2 rad/s x 20 ms would be 12 whole ticks
  const CloudOdometryBag bag = writeCloudOdometryBag(0.0, timing, "ticks");
  ASSERT_EQ(bag.recorded.tf.size(), 26u);
  const PiecewiseTrajectory truth(bag.scenario.start, bag.scenario.pieces);
  const auto nearInteger = [](double x) { return std::abs(x - std::round(x)); };
  double largest_residual = 0.0, largest_heading_error = 0.0;
  for (std::size_t k = 1; k < bag.planar.size(); ++k) {
    const Pose2 step = bag.planar[k - 1].between(bag.planar[k]);
    const double half = 0.5 * step.yaw;
    const double arc =
        std::copysign(std::hypot(step.x, step.y), step.x) * (half == 0.0 ? 1.0 : half / std::sin(half));
    const double difference = step.yaw * 0.235 / 0.001, sum = 2.0 * arc / 0.001;  // nr - nl, nr + nl
    largest_residual = std::max({largest_residual, nearInteger(difference), nearInteger(sum)});
    EXPECT_EQ(std::lround(sum + difference) % 2, 0) << k;
    largest_heading_error =
        std::max(largest_heading_error,
                 std::abs(std::remainder(bag.planar[k].yaw - truth.pose(bag.stamp(k)).yaw, 2 * M_PI)));
  }
  expectTrueHeightAndTilt(
      bag, [&](std::size_t k) { return bag.stamp(k); }, 1e-6);
  std::printf(
      "1 mm ticks on rough ground: increments within %.1e of whole ticks, heading off by up to %.2f deg\n",
      largest_residual, largest_heading_error * 180.0 / M_PI);
  EXPECT_LT(largest_residual, 1e-6);
  EXPECT_LE(largest_heading_error, 2.0 * 0.001 / 0.235 + 1e-9);
  EXPECT_GT(largest_heading_error, 0.0005);
  EXPECT_EQ(bag.truth.odom_timing.tick, 0.001);
  EXPECT_EQ(bag.truth.odom_timing.wheel_base, 0.235);
}

// Recorded 30 ms late in bursts of 3: /tf sample k recorded at the stamp of the last of its burst + 30 ms,
// every message in record order, the clouds still recorded at their last point + 5 ms.
TEST(CloudBagOdometry, LateAndBursty) {
  OdometryTiming timing;
  timing.late = 0.03;
  timing.burst = 3;
  const CloudOdometryBag bag = writeCloudOdometryBag(0.0, timing, "delivery");
  const std::size_t n = bag.recorded.tf.size();
  ASSERT_EQ(n, 26u);
  for (std::size_t k = 0; k < n; ++k) {
    EXPECT_NEAR(bag.stamp(k), -0.1 + static_cast<double>(k) / 50.0, 1e-9) << k;
    const std::size_t last = std::min(n - 1, 3 * (k / 3) + 2);
    EXPECT_NEAR(static_cast<double>(bag.recorded.tf_record_times[k] -
                                    static_cast<core::TimeNs>(bag.recorded.tf[last].header.stamp.toNSec())),
                30e6, 2.0)
        << k;
  }
  EXPECT_TRUE(std::is_sorted(bag.recorded.record_times.begin(), bag.recorded.record_times.end()));
  for (std::size_t k = 0; k < bag.recorded.clouds.size(); ++k)
    EXPECT_NEAR(bag.seconds(bag.recorded.cloud_record_times[k]), 0.1 * static_cast<double>(k + 1) + 0.005,
                1e-3)
        << k;
  EXPECT_EQ(bag.truth.odom_timing.late, 0.03);
  EXPECT_EQ(bag.truth.odom_timing.burst, 3);
}

// All of it together: the same seed writes the same bag, another seed another one; everything in the
// truth file; a bad option refused.
TEST(CloudBagOdometry, EverythingAtOnce) {
  OdometryTiming timing;
  timing.jitter = 0.005;
  timing.rate_min = 5.0;
  timing.rate_max = 7.0;
  timing.tick = 0.001;
  timing.wheel_base = 0.235;
  const CloudOdometryBag first = writeCloudOdometryBag(0.1, timing, "all_a", 7);
  const CloudOdometryBag again = writeCloudOdometryBag(0.1, timing, "all_b", 7);
  const CloudOdometryBag other = writeCloudOdometryBag(0.1, timing, "all_c", 8);
  ASSERT_EQ(first.planar.size(), again.planar.size());
  for (std::size_t k = 0; k < first.planar.size(); ++k) {
    EXPECT_EQ(first.planar[k].x, again.planar[k].x);
    EXPECT_EQ(first.planar[k].yaw, again.planar[k].yaw);
    EXPECT_EQ(first.stamp(k), again.stamp(k));
  }
  EXPECT_NE(first.stamp(1), other.stamp(1));
  EXPECT_EQ(first.truth.odom_noise, 0.1);
  EXPECT_EQ(first.truth.odom_noise_seed, 7u);
  EXPECT_EQ(first.truth.odom_timing.jitter, 0.005);
  EXPECT_EQ(first.truth.odom_timing.rate_max, 7.0);
  EXPECT_EQ(first.truth.odom_timing.wheel_base, 0.235);
  CloudBagOptions options;
  options.tf_margin = -0.1;
  const std::string bag_path = test::temporary("cloud_odom", "invalid.bag");
  EXPECT_THROW(writeCloudBag(first.scenario, options, bag_path, bag_path + ".truth"), std::invalid_argument);
  options = CloudBagOptions();
  options.odom_timing.tick = 0.001;  // without a wheel base
  EXPECT_THROW(writeCloudBag(first.scenario, options, bag_path, bag_path + ".truth"), std::invalid_argument);
  options = CloudBagOptions();
  options.odom_noise = -0.1;
  EXPECT_THROW(writeCloudBag(first.scenario, options, bag_path, bag_path + ".truth"), std::invalid_argument);
}

}  // namespace
}  // namespace lidar_deskew::sim
