// ScanProcessor, the one code path of the node and deskew_bag: message checks and the messages it builds.
#include <gtest/gtest.h>
#include <pcl_conversions/pcl_conversions.h>
#include <pcl_ros/point_cloud.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"

namespace lidar_deskew::ros_adapter {
namespace {

sensor_msgs::LaserScan::Ptr makeScan() {
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  scan->header.frame_id = "laser";
  scan->header.stamp = ros::Time(1000, 500);
  scan->angle_min = -1.0f;
  scan->angle_increment = 0.01f;
  scan->angle_max = -1.0f + 199 * 0.01f;
  scan->time_increment = 1e-4f;
  scan->scan_time = 0.1f;
  scan->range_min = 0.1f;
  scan->range_max = 20.0f;
  scan->ranges.assign(200, 2.0f);
  scan->ranges[7] = 0.0f;
  scan->intensities.assign(200, 50.0f);
  return scan;
}

std::string invalidField(const std::function<void()>& action) {
  try {
    action();
  } catch (const core::InvalidInput& error) {
    return error.field();
  }
  return "";
}

/// A base driving at 1 m/s along x.
core::PoseSamples driving() {
  core::PoseSamples samples;
  for (int k = 0; k <= 4; ++k) {
    samples.add(toNs(ros::Time(1000, 500)) + (k - 2) * 100'000'000,
                mrpt::poses::CPose2D(0.1 * (k - 2), 0.0, 0.0));
  }
  return samples;
}

/// The cloud as a subscriber receives it: serialised by pcl_ros, deserialised as a PointCloud2.
sensor_msgs::PointCloud2 serialized(const DeskewedCloud& cloud) {
  std::vector<uint8_t> buffer(ros::serialization::serializationLength(cloud));
  ros::serialization::OStream out(buffer.data(), static_cast<uint32_t>(buffer.size()));
  ros::serialization::serialize(out, cloud);
  sensor_msgs::PointCloud2 message;
  ros::serialization::IStream in(buffer.data(), static_cast<uint32_t>(buffer.size()));
  ros::serialization::deserialize(in, message);
  return message;
}

TEST(ScanProcessor, RejectsMessagesNamingTheField) {
  ScanProcessor processor(DeskewParams{});
  auto scan = makeScan();
  EXPECT_EQ(invalidField([&] { processor.prepare(scan); }), "");
  scan->header.frame_id.clear();
  EXPECT_EQ(invalidField([&] { processor.prepare(scan); }), "header.frame_id");
  scan = makeScan();
  scan->intensities.resize(3);
  EXPECT_EQ(invalidField([&] { processor.prepare(scan); }), "intensities");
  // Stamped at the end with stamp 0: the first beam would be before time 0.
  DeskewParams at_end;
  at_end.timing.stamp_at = core::StampAt::kEnd;
  ScanProcessor end_processor(at_end);
  scan = makeScan();
  scan->header.stamp = ros::Time(0, 0);
  EXPECT_EQ(invalidField([&] { end_processor.prepare(scan); }), "header.stamp");
  scan->header.stamp = ros::Time(0xFFFFFFFFu, 0);
  EXPECT_EQ(invalidField([&] { processor.prepare(scan); }), "header.stamp");
}

TEST(ScanProcessor, BuildsTheCorrectedScanAndCloud) {
  ScanProcessor processor(DeskewParams{});
  const auto input = makeScan();
  const PreparedScan prepared = processor.prepare(input);
  const core::PoseSamples motion = driving();
  const DeskewedOutputs outputs = processor.correct(prepared, mrpt::poses::CPose3D(), motion);
  const sensor_msgs::LaserScan& scan = *outputs.scan;
  EXPECT_EQ(scan.header.frame_id, "laser");
  // reference start = first beam = stamp (1000 s + 500 ns), on whole microseconds as PCL's stamp
  EXPECT_EQ(scan.header.stamp, ros::Time(1000, 0));
  EXPECT_EQ(scan.angle_min, input->angle_min);
  EXPECT_EQ(scan.angle_increment, input->angle_increment);
  EXPECT_EQ(scan.time_increment, 0.0f);
  EXPECT_EQ(scan.ranges.size(), 200u);
  EXPECT_EQ(scan.intensities.size(), 200u);
  EXPECT_EQ(scan.ranges[7], 0.0f);  // the input's "no return" value
  // Driving at 1 m/s: beam 199, 19.9 ms after the first, is seen 19.9 mm further along x.
  const DeskewedCloud& cloud = *outputs.cloud;
  ASSERT_EQ(cloud.size(), 199u);
  EXPECT_EQ(cloud.header.frame_id, "laser");
  const PointXYZITI& last = cloud.points.back();
  EXPECT_EQ(last.index, 199u);
  const double angle = -1.0 + 199 * static_cast<double>(0.01f);
  EXPECT_NEAR(last.x, 2.0 * std::cos(angle) + 199 * 1e-4, 1e-5);
  EXPECT_NEAR(last.t, 199 * 1e-4 + 500e-9, 1e-8);  // relative to the stamp, 500 ns before beam 0
  EXPECT_EQ(last.intensity, 50.0f);
}

// A stamp with nanoseconds (1000 s + 958 ns): a PCL cloud holds whole microseconds, so both outputs carry
// the reference time on whole microseconds, equal to the nanosecond (an exact-time synchroniser pairs
// them), and t stays relative to that stamp.
TEST(ScanProcessor, BothOutputsCarryOneStampToTheNanosecond) {
  ScanProcessor processor(DeskewParams{});
  const auto input = makeScan();
  input->header.stamp = ros::Time(1000, 958);
  const core::PoseSamples motion = driving();
  const DeskewedOutputs outputs = processor.correct(processor.prepare(input), mrpt::poses::CPose3D(), motion);
  const ros::Time cloud_stamp = pcl_conversions::fromPCL(outputs.cloud->header).stamp;
  EXPECT_EQ(outputs.scan->header.stamp, cloud_stamp);
  EXPECT_EQ(cloud_stamp, ros::Time(1000, 0));
  EXPECT_NEAR(outputs.cloud->points.front().t, 958e-9, 1e-10);  // beam 0 is 958 ns after the stamp
  EXPECT_NEAR(outputs.cloud->points.back().t, 199 * 1e-4 + 958e-9, 5e-9);
}

TEST(ScanProcessor, PassThroughRepublishesTheInputAndStampsTheCloudAtItsReference) {
  DeskewParams params;
  params.deskew.reference = core::Reference::kEnd;
  ScanProcessor processor(params);
  const auto input = makeScan();
  const DeskewedOutputs outputs = processor.passThrough(processor.prepare(input));
  EXPECT_EQ(outputs.scan.get(), input.get());  // the very message, not a copy
  const ros::Time end = input->header.stamp + ros::Duration(199 * static_cast<double>(input->time_increment));
  EXPECT_NEAR((pcl_conversions::fromPCL(outputs.cloud->header).stamp - end).toSec(), 0.0, 1e-6);
  // beam 0 is 19.9 ms before the end, the stamp 500 ns before the end
  EXPECT_NEAR(outputs.cloud->points.front().t, -199 * 1e-4 + 500e-9, 1e-8);
  EXPECT_NEAR(outputs.cloud->points.front().x, 2.0 * std::cos(-1.0), 1e-6);  // uncorrected
}

// The same 1 m/s drive sampled only 0.4 s before and after the scan: an 0.8 s gap. Beyond max_tf_gap
// (0.5 s by default) the scan is refused; with a larger limit it is bridged, exactly here since the
// motion is linear.
TEST(ScanProcessor, RefusesSweepsInsideALongerGapThanMaxTfGap) {
  core::PoseSamples sparse;
  const core::TimeNs stamp = toNs(ros::Time(1000, 500));
  sparse.add(stamp - 400'000'000, mrpt::poses::CPose2D(-0.4, 0.0, 0.0));
  sparse.add(stamp + 400'000'000, mrpt::poses::CPose2D(0.4, 0.0, 0.0));
  ScanProcessor strict(DeskewParams{});
  const PreparedScan prepared = strict.prepare(makeScan());
  EXPECT_THROW(strict.correct(prepared, mrpt::poses::CPose3D(), sparse), TfGapTooLong);
  EXPECT_NO_THROW(strict.correct(prepared, mrpt::poses::CPose3D(), driving()));  // 0.1 s apart

  DeskewParams tolerant;
  tolerant.max_tf_gap = 1.0;
  ScanProcessor bridging(tolerant);
  const DeskewedOutputs outputs = bridging.correct(prepared, mrpt::poses::CPose3D(), sparse);
  const double angle = -1.0 + 199 * static_cast<double>(0.01f);
  EXPECT_NEAR(outputs.cloud->points.back().x, 2.0 * std::cos(angle) + 199 * 1e-4, 1e-5);
}

// A scan without a single return gives an empty cloud, which pcl_ros must serialize into a valid empty
// PointCloud2 with our six fields (it used to memcpy from a null pointer: found by fuzz_messages).
TEST(ScanProcessor, EmptyCloudSerializesAsAValidPointCloud2) {
  ScanProcessor processor(DeskewParams{});
  auto input = makeScan();
  input->ranges.assign(200, 0.0f);
  const DeskewedOutputs outputs =
      processor.correct(processor.prepare(input), mrpt::poses::CPose3D(), driving());
  ASSERT_TRUE(outputs.cloud->empty());
  EXPECT_NE(outputs.cloud->points.data(), nullptr);
  const sensor_msgs::PointCloud2 message = serialized(*outputs.cloud);
  EXPECT_EQ(message.width * message.height, 0u);
  EXPECT_TRUE(message.data.empty());
  ASSERT_EQ(message.fields.size(), 6u);
  EXPECT_EQ(message.fields[5].name, "index");
  EXPECT_EQ(message.header.frame_id, "laser");
}

// The serialised cloud's bytes outside its fields (data[3] of x y z, the 4 bytes after index) are zero,
// not what the stack held: the same scan gives the same bytes, and a bag of outputs compares with cmp.
TEST(ScanProcessor, CloudBytesOutsideTheFieldsAreZero) {
  ScanProcessor processor(DeskewParams{});
  const DeskewedOutputs outputs =
      processor.correct(processor.prepare(makeScan()), mrpt::poses::CPose3D(), driving());
  const sensor_msgs::PointCloud2 message = serialized(*outputs.cloud);
  ASSERT_EQ(message.width, 199u);
  std::vector<bool> in_field(message.point_step, false);
  for (const sensor_msgs::PointField& field : message.fields) {
    const auto size = static_cast<uint32_t>(::sizeOfPointField(field.datatype)) * field.count;
    for (uint32_t b = 0; b < size; ++b)
      in_field.at(field.offset + b) = true;
  }
  ASSERT_EQ(std::count(in_field.begin(), in_field.end(), false), 8);
  std::size_t nonzero = 0;
  for (std::size_t i = 0; i < message.data.size(); ++i) {
    nonzero += !in_field[i % message.point_step] && message.data[i] != 0;
  }
  EXPECT_EQ(nonzero, 0u);
}

}  // namespace
}  // namespace lidar_deskew::ros_adapter
