// libFuzzer target for the message path: arbitrary bytes deserialized as a sensor_msgs/LaserScan (any
// sizes, NaN/inf fields, mismatched arrays, any stamp), then checked, timed, corrected and turned into
// the output messages by ScanProcessor, as the node and deskew_bag do. Both output clouds (corrected and
// pass-through) then go through the PointCloud2 conversion subscribers see: serialized by pcl_ros,
// read back as sensor_msgs/PointCloud2, layout and every value checked. And the scan goes through the
// whole pipeline between two good scans, with a real tf2 buffer (stale tf, a transform at its stamp):
// it never throws and never costs the good ones.
#include <fuzzer/FuzzedDataProvider.h>
#include <pcl_ros/point_cloud.h>  // the clouds serialized as subscribers get them
#include <ros/serialization.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_pipeline.h"
#include "lidar_deskew/ros/scan_processor.h"

using namespace lidar_deskew;

namespace {

/// The cloud as subscribers outside the manager get it: serialized by pcl_ros from our point type,
/// read back as a sensor_msgs/PointCloud2. Its layout must be x y z intensity t (float32) index
/// (uint32), dense rows, and every value must read back unchanged through PointCloud2 iterators.
void checkCloudOnTheWire(const ros_adapter::DeskewedCloud& cloud) {
  std::vector<uint8_t> buffer(ros::serialization::serializationLength(cloud));
  ros::serialization::OStream out(buffer.data(), static_cast<uint32_t>(buffer.size()));
  ros::serialization::serialize(out, cloud);
  sensor_msgs::PointCloud2 message;
  ros::serialization::IStream in(buffer.data(), static_cast<uint32_t>(buffer.size()));
  ros::serialization::deserialize(in, message);

  const std::vector<std::pair<std::string, uint8_t>> expected = {
      {"x", sensor_msgs::PointField::FLOAT32}, {"y", sensor_msgs::PointField::FLOAT32},
      {"z", sensor_msgs::PointField::FLOAT32}, {"intensity", sensor_msgs::PointField::FLOAT32},
      {"t", sensor_msgs::PointField::FLOAT32}, {"index", sensor_msgs::PointField::UINT32}};
  if (message.fields.size() != expected.size())
    std::abort();
  for (std::size_t f = 0; f < expected.size(); ++f) {
    const sensor_msgs::PointField& field = message.fields[f];
    if (field.name != expected[f].first || field.datatype != expected[f].second || field.count != 1 ||
        field.offset + 4 > message.point_step)
      std::abort();
  }
  const std::size_t count = cloud.points.size();
  if (message.height != 1 || message.width != count ||
      message.row_step != message.width * message.point_step ||
      message.data.size() != std::size_t{message.row_step} * message.height ||
      message.header.frame_id != cloud.header.frame_id)
    std::abort();
  if (count == 0)
    return;  // sensor_msgs' iterators call data.front() on empty data (their UB, noted, not ours)
  sensor_msgs::PointCloud2ConstIterator<float> x(message, "x"), y(message, "y"), z(message, "z");
  sensor_msgs::PointCloud2ConstIterator<float> intensity(message, "intensity"), t(message, "t");
  sensor_msgs::PointCloud2ConstIterator<uint32_t> index(message, "index");
  for (std::size_t i = 0; i < count; ++i, ++x, ++y, ++z, ++intensity, ++t, ++index) {
    const PointXYZITI& point = cloud.points[i];
    const auto same = [](float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; };
    if (!same(*x, point.x) || !same(*y, point.y) || !same(*z, point.z) ||
        !same(*intensity, point.intensity) || !same(*t, point.t) || *index != point.index)
      std::abort();
  }
}

/// The fuzzed scan in a stream, through the pipeline of the node and deskew_bag with a real tf2 buffer:
/// a good scan before it and one after it, tf at 50 Hz covering both, and (by the scan's seq) a stray
/// publisher's stale tf at 2 Hz, or a transform stamped with the fuzzed scan's stamp. Nothing may
/// throw; every scan is accounted for once; with tf left alone both good scans are corrected whatever
/// the fuzzed one holds (its stamp 0, in 2105, anything: it never holds the stream back).
void throughThePipeline(const sensor_msgs::LaserScan::ConstPtr& fuzzed) {
  const bool stray = (fuzzed->header.seq & 1u) != 0;
  const bool tf_at_its_stamp = (fuzzed->header.seq & 2u) != 0;
  std::vector<std::uint64_t> corrected;
  ros_adapter::ScanPipeline pipeline(
      ros_adapter::DeskewParams(),
      [&](const ros_adapter::PipelineResult& result) {
        if (result.corrected)
          corrected.push_back(result.id);
      },
      [](ros_adapter::PipelineEvent, const std::string&) {});
  const core::TimeNs epoch = 1'700'000'000'000'000'000;
  const auto stamp = [&](double t) { return ros_adapter::toRosTime(epoch + core::secondsToNs(t)); };
  const auto transform = [&](const std::string& parent, const std::string& child, const ros::Time& at,
                             double x) {
    geometry_msgs::TransformStamped link;
    link.header.frame_id = parent;
    link.header.stamp = at;
    link.child_frame_id = child;
    link.transform = ros_adapter::toTransform(mrpt::poses::CPose3D(x, 0.1 * x, 0.0, 0.3 * x, 0.0, 0.0));
    return link;
  };
  // Its mount, unless its frame is one of the tree's (a frame tf would then have twice).
  const std::string frame = ros_adapter::normalizedFrame(fuzzed->header.frame_id);
  pipeline.addTransforms({transform("base_link", "laser", stamp(0.0), 0.1)}, true, -4.0);
  if (!frame.empty() && frame != "laser" && frame != "base_link" && frame != "odom")
    pipeline.addTransforms({transform("base_link", frame, stamp(0.0), 0.2)}, true, -4.0);
  double tf_until = -4.0;
  const auto tfUntil = [&](double t) {
    for (; tf_until + 0.02 <= t + 1e-9; tf_until += 0.02) {
      const double at = tf_until + 0.02;
      pipeline.addTransforms({transform("odom", "base_link", stamp(at), at)}, false, at);
      if (stray && std::fmod(at + 4.0 + 1e-9, 0.5) < 0.02)
        pipeline.addTransforms({transform("odom", "base_link", stamp(at - 3.0), 9.0)}, false, at);
    }
  };
  const auto goodScan = [&](double t) {
    auto scan = boost::make_shared<sensor_msgs::LaserScan>();
    scan->header.stamp = stamp(t);
    scan->header.frame_id = "laser";
    scan->angle_min = -1.0f;
    scan->angle_increment = 0.01f;
    scan->time_increment = 0.0001f;
    scan->range_min = 0.1f;
    scan->range_max = 10.0f;
    scan->ranges.assign(200, 2.0f);
    return scan;
  };
  tfUntil(0.25);
  pipeline.add(goodScan(0.2), 0.25, 1);
  pipeline.add(fuzzed, 0.26, 2);
  if (tf_at_its_stamp)
    pipeline.addTransforms({transform("odom", "base_link", fuzzed->header.stamp, 1.0)}, false, 0.27);
  tfUntil(0.6);
  pipeline.add(goodScan(0.5), 0.55, 3);
  tfUntil(0.7);
  pipeline.expire(5.0);
  pipeline.flush();
  const ros_adapter::PipelineCounters& c = pipeline.counters();
  if (pipeline.waiting() != 0 || c.received != 3 ||
      c.published + c.passed_through + c.dropped_invalid + c.dropped_tf + c.dropped_mount + c.dropped_queue !=
          3)
    std::abort();
  const auto served = [&](std::uint64_t id) {
    return std::find(corrected.begin(), corrected.end(), id) != corrected.end();
  };
  if (!tf_at_its_stamp && (!served(1) || !served(3) || c.time_jumps != 0)) {
    std::fprintf(stderr, "good scans served: %d %d; time jumps %llu; fuzzed stamp %u.%09u frame '%s'\n",
                 served(1), served(3), static_cast<unsigned long long>(c.time_jumps),
                 fuzzed->header.stamp.sec, fuzzed->header.stamp.nsec, fuzzed->header.frame_id.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* bytes, size_t size) {
  FuzzedDataProvider data(bytes, size);
  ros_adapter::DeskewParams params;
  params.timing.stamp_at = data.ConsumeBool() ? core::StampAt::kStart : core::StampAt::kEnd;
  params.deskew.reference = static_cast<core::Reference>(data.ConsumeIntegralInRange<int>(0, 2));
  const std::vector<uint8_t> message_bytes = data.ConsumeRemainingBytes<uint8_t>();
  if (message_bytes.empty())
    return 0;  // roscpp's IStream adds an offset to the null pointer of an empty buffer (its UB, not ours)

  // roscpp's deserializer sizes arrays from their declared length before checking the buffer holds
  // them: a small message declaring 2^31 ranges allocates gigabytes there (its weakness, noted, not
  // ours). Walk the LaserScan layout first and skip such input.
  {
    std::size_t at = 0;
    const auto skipArray = [&](std::size_t element) {
      if (at + 4 > message_bytes.size())
        return false;
      uint32_t count;
      std::memcpy(&count, message_bytes.data() + at, 4);
      at += 4;
      if (count > (message_bytes.size() - at) / element)
        return false;
      at += count * element;
      return true;
    };
    at = 12;  // header.seq, header.stamp
    if (!skipArray(1))
      return 0;   // header.frame_id
    at += 7 * 4;  // angle_min ... range_max
    if (!skipArray(4) || !skipArray(4))
      return 0;  // ranges, intensities
  }
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  try {
    ros::serialization::IStream stream(const_cast<uint8_t*>(message_bytes.data()),
                                       static_cast<uint32_t>(message_bytes.size()));
    ros::serialization::deserialize(stream, *scan);
  } catch (const ros::Exception&) {
    return 0;  // not a LaserScan: roscpp would not deliver it
  }
  if (scan->ranges.size() > 100000)
    return 0;  // keep runs short; the size limit itself is tested in test_timing
  throughThePipeline(scan);
  // A base driving and turning around the scan's stamp (when the stamp allows it).
  core::PoseSamples motion;
  const core::TimeNs stamp = static_cast<core::TimeNs>(scan->header.stamp.toNSec());
  for (int k = -5; k <= 5; ++k) {
    const core::TimeNs time = stamp + k * 200'000'000LL;
    if (time >= 0 && (motion.empty() || time > motion.lastTime()))
      motion.add(time, mrpt::poses::CPose2D(0.3 * k, 0.1 * k, 0.2 * k));
  }
  ros_adapter::ScanProcessor processor(params);
  try {
    const ros_adapter::PreparedScan prepared = processor.prepare(scan);
    const ros_adapter::DeskewedOutputs outputs = processor.correct(prepared, mrpt::poses::CPose3D(), motion);
    if (outputs.scan->ranges.size() != scan->ranges.size())
      std::abort();
    for (const auto& point : outputs.cloud->points) {
      if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z))
        std::abort();
    }
    checkCloudOnTheWire(*outputs.cloud);
    checkCloudOnTheWire(*processor.passThrough(prepared).cloud);
  } catch (const core::InvalidInput&) {
  } catch (const core::MotionUnavailable&) {
  }
  return 0;
}
