// libFuzzer target for the message path: arbitrary bytes deserialized as a sensor_msgs/LaserScan (any
// sizes, NaN/inf fields, mismatched arrays, any stamp), then checked, timed, corrected and turned into
// the output messages by ScanProcessor, as the node and deskew_bag do.
#include <fuzzer/FuzzedDataProvider.h>
#include <ros/serialization.h>

#include <cstdlib>
#include <cstring>

#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"

using namespace lidar_deskew;

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
    processor.passThrough(prepared);
  } catch (const core::InvalidInput&) {
  } catch (const core::MotionUnavailable&) {
  }
  return 0;
}
