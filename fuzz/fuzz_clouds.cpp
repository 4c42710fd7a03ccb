// libFuzzer target for the PointCloud2 path, two ways in (the first byte chooses): arbitrary bytes
// deserialized as a sensor_msgs/PointCloud2, or a cloud built field by field (x/y/z and the time
// fields' names with any datatype, offset and count; point_step, row_step, width, height and the data's
// size consistent or not; is_bigendian; any stamp; time values of any magnitude, NaN/inf, spans beyond
// max_sweep_duration; organized or dense), with the parameters drawn too. Then as the node does:
// CloudProcessor::prepare, correct against a tf buffer or pose samples covering the sweep (or not),
// passThrough. A malformed cloud must be refused naming a field; an output must keep the input's
// layout, leave every no-return point's bytes as they were, hold finite x y z at every return, and its
// planar scan only inf or ranges in [0, range_max].
#include <fuzzer/FuzzedDataProvider.h>
#include <ros/serialization.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <limits>

#include "lidar_deskew/ros/cloud_processor.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/ros/scan_processor.h"
#include "lidar_deskew/ros/tf_feed.h"

using namespace lidar_deskew;
using sensor_msgs::PointField;

namespace {

const char* const kNames[] = {"x",           "y",      "z",         "t",    "time", "timestamp", "time_stamp",
                              "offset_time", "stamps", "intensity", "ring", "",     "T",         "x "};
constexpr core::TimeNs kSecond = 1'000'000'000;
constexpr core::TimeNs kRosTimeEnd = (core::TimeNs{1} << 32) * kSecond;  // [ns] ros::Time's end

template <typename T>
T pick(FuzzedDataProvider& data, std::initializer_list<T> choices) {
  return *(choices.begin() + data.ConsumeIntegralInRange<std::size_t>(0, choices.size() - 1));
}

/// The parameters a node could be started with (always valid: bad ones stop the node at start-up).
ros_adapter::DeskewParams drawParams(FuzzedDataProvider& data) {
  ros_adapter::DeskewParams params;
  params.cloud_time.field =
      pick<const char*>(data, {"", "", "", "t", "time", "timestamp", "stamps", "ring", "x"});
  params.cloud_time.unit = pick<const char*>(data, {"auto", "auto", "s", "ms", "us", "ns"});
  params.cloud_time.base = pick<const char*>(data, {"auto", "auto", "header", "absolute"});
  params.timing.max_sweep_duration = pick<double>(data, {1.0, 0.1, 0.05, 60.0, 1e-6});
  params.azimuth.enabled = data.ConsumeBool();
  params.azimuth.direction = data.ConsumeBool() ? "cw" : "ccw";
  params.azimuth.period = std::min(pick<double>(data, {0.1, 0.05, 1.0}), params.timing.max_sweep_duration);
  params.azimuth.stamp_at = data.ConsumeBool() ? "start" : "end";
  params.cloud_scan.enabled = data.ConsumeBool();
  // (ConsumeFloatingPointInRange may round past its bounds: clamped.)
  params.cloud_scan.angle_min = std::clamp(data.ConsumeFloatingPointInRange(-3.15, 3.0), -3.15, 3.0);
  params.cloud_scan.angle_max =
      std::clamp(data.ConsumeFloatingPointInRange(params.cloud_scan.angle_min + 0.01, 3.15),
                 params.cloud_scan.angle_min + 0.01, 3.15);
  params.cloud_scan.angle_increment = pick<double>(data, {0.00436332, 1e-5, 0.1, 1.0});
  params.cloud_scan.height_min = std::clamp(data.ConsumeFloatingPointInRange(-100.0, 100.0), -100.0, 100.0);
  params.cloud_scan.height_max =
      std::clamp(data.ConsumeFloatingPointInRange(params.cloud_scan.height_min, 100.0),
                 params.cloud_scan.height_min, 100.0);
  params.cloud_scan.range_max = pick<double>(data, {100.0, 1e-3, 10000.0});
  params.deskew.reference = static_cast<core::Reference>(data.ConsumeIntegralInRange<int>(0, 2));
  params.exact = data.ConsumeBool();
  params.deskew.knot_interval = params.exact ? 0.0 : pick<double>(data, {0.005, 1e-5, 0.1, 1.0});
  params.max_tf_gap = pick<double>(data, {0.5, 0.0, 0.01});
  params.validate();
  return params;
}

/// Writes `value` as a field of `datatype` would hold it (clamped, NaN as 0 for integers: the
/// fuzzer's own conversions must be defined).
void writeAs(std::uint8_t* at, std::uint8_t datatype, double value) {
  ros_adapter::withFieldType(datatype, [&](auto typed) {
    using T = decltype(typed);
    if constexpr (std::is_integral_v<T>) {
      const double low = static_cast<double>(std::numeric_limits<T>::lowest());
      const double high = static_cast<double>(std::numeric_limits<T>::max());
      typed = std::isnan(value) ? T{0}
              : value <= low    ? std::numeric_limits<T>::lowest()
              : value >= high   ? std::numeric_limits<T>::max()
                                : static_cast<T>(value);
    } else {
      const double most = static_cast<double>(std::numeric_limits<T>::max());
      typed = std::isfinite(value) ? static_cast<T>(std::clamp(value, -most, most)) : static_cast<T>(value);
    }
    std::memcpy(at, &typed, sizeof typed);
  });
}

/// A cloud built from the fuzzer's choices: mostly plausible, any part of it possibly not.
sensor_msgs::PointCloud2::Ptr buildCloud(FuzzedDataProvider& data) {
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  cloud->header.frame_id = data.ConsumeIntegralInRange<int>(0, 15) == 0 ? "" : "lidar";
  switch (data.ConsumeIntegralInRange<int>(0, 4)) {
    case 0:
      cloud->header.stamp = ros::Time(0, 0);
      break;
    case 1:
      cloud->header.stamp = ros::Time(data.ConsumeIntegralInRange<std::uint32_t>(0, 5),
                                      data.ConsumeIntegralInRange<std::uint32_t>(0, 999'999'999));
      break;
    case 2:
      cloud->header.stamp = ros::Time(
          std::numeric_limits<std::uint32_t>::max() - data.ConsumeIntegralInRange<std::uint32_t>(0, 200),
          data.ConsumeIntegralInRange<std::uint32_t>(0, 999'999'999));
      break;
    case 3:
      cloud->header.stamp = ros::Time(data.ConsumeIntegral<std::uint32_t>(),
                                      data.ConsumeIntegralInRange<std::uint32_t>(0, 999'999'999));
      break;
    default:
      cloud->header.stamp =
          ros::Time(1'700'000'000, data.ConsumeIntegralInRange<std::uint32_t>(0, 999'999'999));
  }

  // The fields: x y z of one floating type, then a few others, packed; then mutations of any of it.
  const std::uint8_t coordinate = data.ConsumeBool() ? PointField::FLOAT64 : PointField::FLOAT32;
  std::uint32_t end = 0;
  const auto addField = [&](const std::string& name, std::uint8_t datatype) {
    PointField field;
    field.name = name;
    field.datatype = datatype;
    field.offset = end;
    field.count = 1;
    end += datatype == PointField::FLOAT64  ? 8
           : datatype <= PointField::UINT8  ? 1
           : datatype <= PointField::UINT16 ? 2
                                            : 4;
    cloud->fields.push_back(field);
  };
  for (const char* axis : {"x", "y", "z"})
    addField(axis, coordinate);
  for (int extra = data.ConsumeIntegralInRange<int>(0, 3); extra > 0; --extra) {
    addField(kNames[data.ConsumeIntegralInRange<std::size_t>(3, std::size(kNames) - 1)],
             data.ConsumeIntegralInRange<std::uint8_t>(1, 8));
  }
  for (int mutations = data.ConsumeIntegralInRange<int>(0, 3); mutations > 0 && !cloud->fields.empty();
       --mutations) {
    PointField& field = cloud->fields[data.ConsumeIntegralInRange<std::size_t>(0, cloud->fields.size() - 1)];
    switch (data.ConsumeIntegralInRange<int>(0, 5)) {
      case 0:
        field.datatype = data.ConsumeIntegral<std::uint8_t>();
        break;
      case 1:
        field.offset = data.ConsumeIntegralInRange<std::uint32_t>(0, end + 8);
        break;
      case 2:
        field.count = data.ConsumeIntegralInRange<std::uint32_t>(0, 3);
        break;
      case 3:
        field.name = kNames[data.ConsumeIntegralInRange<std::size_t>(0, std::size(kNames) - 1)];
        break;
      case 4:
        cloud->fields.erase(cloud->fields.begin() + (&field - cloud->fields.data()));
        break;
      default:
        field.offset = data.ConsumeIntegral<std::uint32_t>();
    }
  }
  cloud->is_bigendian = data.ConsumeIntegralInRange<int>(0, 15) == 0;
  cloud->point_step = end + data.ConsumeIntegralInRange<std::uint32_t>(0, 8);
  if (data.ConsumeIntegralInRange<int>(0, 15) == 0)
    cloud->point_step = data.ConsumeIntegralInRange<std::uint32_t>(0, 64);
  const bool organized = data.ConsumeBool();
  cloud->height = organized ? data.ConsumeIntegralInRange<std::uint32_t>(2, 8) : 1;
  cloud->width = data.ConsumeIntegralInRange<std::uint32_t>(0, 64);
  cloud->row_step = cloud->width * cloud->point_step + data.ConsumeIntegralInRange<std::uint32_t>(0, 4);
  switch (data.ConsumeIntegralInRange<int>(0, 15)) {
    case 0:
      cloud->row_step = data.ConsumeIntegralInRange<std::uint32_t>(0, 4096);
      break;
    case 1:
      cloud->height = data.ConsumeIntegral<std::uint32_t>();
      break;
    case 2:
      cloud->width = data.ConsumeIntegral<std::uint32_t>();
      break;
    case 3:
      cloud->height = 0;
      break;
  }
  std::size_t size = std::min<std::uint64_t>(std::uint64_t{cloud->height} * cloud->row_step, 1 << 20);
  if (data.ConsumeIntegralInRange<int>(0, 15) == 0)
    size = data.ConsumeIntegralInRange<std::size_t>(0, size + 16);
  cloud->data.assign(size, 0);
  cloud->is_dense = !organized;

  // The points: returns, no-returns (NaN, inf, zeros) and time values, in the first time field's type.
  const PointField* x = nullptr;
  const PointField* y = nullptr;
  const PointField* z = nullptr;
  const PointField* time = nullptr;
  for (const PointField& field : cloud->fields) {
    if (field.name == "x" && x == nullptr)
      x = &field;
    else if (field.name == "y" && y == nullptr)
      y = &field;
    else if (field.name == "z" && z == nullptr)
      z = &field;
    else if (field.name != "intensity" && field.name != "ring" && time == nullptr)
      time = &field;
  }
  const double unit = pick<double>(data, {1.0, 1e-3, 1e-6, 1e-9});
  const bool absolute = data.ConsumeBool();
  const double span = pick<double>(data, {0.1, 0.0, 1e-3, 0.999, 1.5, 100.0, 1e12});
  const double start = (absolute ? cloud->header.stamp.toSec() : 0.0) +
                       pick<double>(data, {0.0, -span, -0.5 * span, 0.05, -1e9, 1e300});
  const double no_return = pick<double>(
      data, {0.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()});
  const bool by_column = data.ConsumeBool();  // one time per column, as multi-line LIDARs fire
  const std::size_t count =
      std::min<std::size_t>(std::size_t{cloud->width} * cloud->height, 512);  // the rest stays zeros
  for (std::size_t i = 0; i < count && data.remaining_bytes() > 0; ++i) {
    const std::size_t at = ros_adapter::pointOffset(*cloud, i);
    const std::size_t column = i % std::max<std::uint32_t>(cloud->width, 1);
    const double fraction =
        static_cast<double>(by_column ? column : i) /
        static_cast<double>(std::max<std::size_t>(by_column ? cloud->width : count, 2) - 1);
    double seconds = start + span * fraction;
    const int kind = data.ConsumeIntegralInRange<int>(0, 31);
    double value = seconds / unit;
    if (kind == 0)
      value = std::numeric_limits<double>::quiet_NaN();
    else if (kind == 1)
      value = data.ConsumeBool() ? std::numeric_limits<double>::infinity() : -1e300;
    else if (kind == 2)
      value = data.ConsumeFloatingPoint<double>();
    const bool is_return = data.ConsumeIntegralInRange<int>(0, 7) != 0;
    const double coordinates[3] = {is_return ? data.ConsumeFloatingPointInRange(-200.0, 200.0) : no_return,
                                   is_return ? data.ConsumeFloatingPointInRange(-200.0, 200.0) : no_return,
                                   is_return ? data.ConsumeFloatingPointInRange(-5.0, 5.0) : no_return};
    const PointField* axes[3] = {x, y, z};
    for (int k = 0; k < 3; ++k) {
      if (axes[k] != nullptr && at + axes[k]->offset + 8 <= cloud->data.size())
        writeAs(cloud->data.data() + at + axes[k]->offset, axes[k]->datatype, coordinates[k]);
    }
    if (time != nullptr && at + std::uint64_t{time->offset} + 8 <= cloud->data.size())
      writeAs(cloud->data.data() + at + time->offset, time->datatype, value);
  }
  // Whatever is left goes over the data as it is.
  const std::vector<std::uint8_t> rest = data.ConsumeRemainingBytes<std::uint8_t>();
  if (!cloud->data.empty()) {
    for (std::size_t k = 0; k + 4 < rest.size(); k += 5) {
      std::uint32_t where;
      std::memcpy(&where, &rest[k], 4);
      cloud->data[where % cloud->data.size()] = rest[k + 4];
    }
  }
  return cloud;
}

/// Arbitrary bytes as a PointCloud2, when roscpp would deliver them (null otherwise).
sensor_msgs::PointCloud2::Ptr deserializeCloud(const std::vector<std::uint8_t>& bytes) {
  if (bytes.empty())
    return nullptr;  // roscpp's IStream adds an offset to the null pointer of an empty buffer
  // roscpp's deserializer sizes arrays from their declared length before checking the buffer holds
  // them (its weakness, noted with fuzz_messages): walk the layout first and skip such input.
  std::size_t at = 0;
  const auto skip = [&](std::size_t bytes_count) {
    if (at + bytes_count > bytes.size())
      return false;
    at += bytes_count;
    return true;
  };
  const auto count = [&](std::size_t element, std::uint32_t& n) {
    if (at + 4 > bytes.size())
      return false;
    std::memcpy(&n, bytes.data() + at, 4);
    at += 4;
    return n <= (bytes.size() - at) / element;
  };
  std::uint32_t n = 0;
  if (!skip(12) || !count(1, n) || !skip(n) || !skip(8))  // header (seq, stamp, frame_id), height, width
    return nullptr;
  std::uint32_t fields = 0;
  if (!count(13, fields))  // each: name (4 + n), offset 4, datatype 1, count 4
    return nullptr;
  for (std::uint32_t f = 0; f < fields; ++f) {
    if (!count(1, n) || !skip(n) || !skip(9))
      return nullptr;
  }
  if (!skip(9) || !count(1, n))  // is_bigendian, point_step, row_step; data
    return nullptr;
  auto cloud = boost::make_shared<sensor_msgs::PointCloud2>();
  try {
    ros::serialization::IStream stream(const_cast<std::uint8_t*>(bytes.data()),
                                       static_cast<std::uint32_t>(bytes.size()));
    ros::serialization::deserialize(stream, *cloud);
  } catch (const ros::Exception&) {
    return nullptr;  // not a PointCloud2: roscpp would not deliver it
  }
  return cloud;
}

/// x y z of the point at `point` (of the coordinate type of `x`): a return when finite and not the origin.
bool isReturn(const std::uint8_t* point, const PointField& x, const PointField& y, const PointField& z) {
  const double p[3] = {ros_adapter::readNumber(point + x.offset, x.datatype),
                       ros_adapter::readNumber(point + y.offset, y.datatype),
                       ros_adapter::readNumber(point + z.offset, z.datatype)};
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]) &&
         (p[0] != 0.0 || p[1] != 0.0 || p[2] != 0.0);
}

const PointField& fieldNamed(const sensor_msgs::PointCloud2& cloud, const char* name) {
  for (const PointField& field : cloud.fields) {
    if (field.name == name)
      return field;
  }
  std::abort();  // prepare() accepted a cloud without it
}

void checkScan(const sensor_msgs::LaserScan::ConstPtr& scan, const ros_adapter::DeskewParams& params) {
  if (params.cloud_scan.enabled != (scan != nullptr))
    std::abort();
  if (scan == nullptr)
    return;
  if (scan->ranges.empty())
    std::abort();
  for (float range : scan->ranges) {
    if (!(std::isinf(range) && range > 0) &&
        !(range >= 0.0f && range <= static_cast<float>(params.cloud_scan.range_max)))
      std::abort();
  }
}

/// The output cloud against the input: the same layout, no-return bytes as they were, finite returns.
void checkOutput(const sensor_msgs::PointCloud2& in, const sensor_msgs::PointCloud2& out,
                 const ros_adapter::PreparedCloud& prepared) {
  if (out.fields.size() != in.fields.size() || out.width != in.width || out.height != in.height ||
      out.point_step != in.point_step || out.row_step != in.row_step || out.data.size() != in.data.size() ||
      out.is_bigendian != in.is_bigendian || out.header.frame_id != in.header.frame_id)
    std::abort();
  for (std::size_t f = 0; f < in.fields.size(); ++f) {
    if (out.fields[f].name != in.fields[f].name || out.fields[f].offset != in.fields[f].offset ||
        out.fields[f].datatype != in.fields[f].datatype || out.fields[f].count != in.fields[f].count)
      std::abort();
  }
  const core::TimeNs stamp = ros_adapter::toNs(out.header.stamp);
  if (stamp < prepared.earliest() || stamp > prepared.latest())
    std::abort();
  const PointField &x = fieldNamed(in, "x"), &y = fieldNamed(in, "y"), &z = fieldNamed(in, "z");
  std::vector<bool> touched(in.data.size(), false);  // bytes of returns: may change
  const std::size_t count = static_cast<std::size_t>(in.width) * in.height;
  std::size_t returns = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t at = ros_adapter::pointOffset(in, i);
    if (!isReturn(in.data.data() + at, x, y, z))
      continue;
    ++returns;
    std::fill(touched.begin() + at, touched.begin() + at + in.point_step, true);
    for (const PointField* axis : {&x, &y, &z}) {
      if (!std::isfinite(ros_adapter::readNumber(out.data.data() + at + axis->offset, axis->datatype)))
        std::abort();
    }
  }
  if (returns != prepared.points.size())
    std::abort();
  for (std::size_t k = 0; k < in.data.size(); ++k) {
    if (!touched[k] && out.data[k] != in.data[k])
      std::abort();
  }
}

/// What prepare() promises of a cloud it accepted.
void checkPrepared(const ros_adapter::PreparedCloud& prepared, const ros_adapter::DeskewParams& params) {
  const std::size_t returns = prepared.points.size();
  if (prepared.byte_offsets.size() != returns || prepared.firings.of_point.size() != returns ||
      prepared.firing_times.size() != prepared.firings.offsets.size())
    std::abort();
  if (prepared.first < 0 || prepared.last < prepared.first || prepared.last >= kRosTimeEnd ||
      core::nsToSeconds(prepared.last - prepared.first) > params.timing.max_sweep_duration)
    std::abort();
  for (std::size_t i = 0; i < returns; ++i) {
    if (!prepared.points[i].allFinite() || prepared.firings.of_point[i] >= prepared.firing_times.size())
      std::abort();
    const core::TimeNs time = prepared.timeOf(i);
    if (time < prepared.first || time > prepared.last)
      std::abort();
  }
  for (double offset : prepared.firings.offsets) {
    if (!std::isfinite(offset))
      std::abort();
  }
}

void process(const sensor_msgs::PointCloud2::Ptr& cloud, const ros_adapter::DeskewParams& params, bool use_tf,
             int coverage) {
  ros_adapter::CloudProcessor processor(params);
  ros_adapter::PreparedCloud prepared;
  try {
    prepared = processor.prepare(cloud);
  } catch (const core::InvalidInput& error) {
    // A malformed cloud is dropped with an error naming the field. (Not what() itself: a field name may
    // hold NUL bytes, which end the C string early.)
    if (error.field().empty())
      std::abort();
    return;
  }
  checkPrepared(prepared, params);
  checkScan(processor.passThrough(prepared).scan, params);
  if (processor.passThrough(prepared).cloud != cloud)
    std::abort();

  // A base driving and turning across the sweep: covered (0), short at the end (1) or with a gap (2).
  const core::TimeNs first = prepared.earliest(), last = prepared.latest();
  const core::TimeNs step = std::max<core::TimeNs>((last - first) / 4, 20'000'000);
  const mrpt::poses::CPose3D mount(0.1, 0.0, 0.2, 0.01, 0.02, 0.0);
  core::PoseSamples samples;
  ros_adapter::TfFeed feed("odom", "base_link", 200.0, nullptr);
  for (int k = -2; k <= 6; ++k) {
    const core::TimeNs time = first + k * step + (k == 6 ? step : 0);
    if ((coverage == 1 && time >= last) || (coverage == 2 && k == 2) || time < 0 || time >= kRosTimeEnd)
      continue;
    const mrpt::poses::CPose3D pose(0.3 * k, 0.1 * k, 0.01 * k, 0.2 * k, 0.01, -0.02 * k);
    samples.add(time, pose);
    geometry_msgs::TransformStamped transform;
    transform.header.frame_id = "odom";
    transform.child_frame_id = "base_link";
    transform.header.stamp = ros_adapter::toRosTime(time);
    transform.transform = ros_adapter::toTransform(pose);
    // Near ros::Time's end tf2 throws on adding it ("Time is out of dual 32-bit range"): TfFeed
    // refuses it and goes on.
    feed.add(transform, false);
  }
  // Whether and why tf covers the sweep: answered, never thrown, whatever the stamps.
  std::string why;
  const ros_adapter::Coverage coverage_now = feed.coverage(first, last, &why);
  if (coverage_now == ros_adapter::Coverage::kNever && why.empty())
    std::abort();
  if (coverage_now != ros_adapter::Coverage::kCovered && feed.whyNotCovered(first, last, last).empty())
    std::abort();
  try {
    const ros_adapter::CloudOutputs outputs = use_tf ? processor.correct(prepared, mount, feed.motion())
                                                     : processor.correct(prepared, mount, samples);
    checkOutput(*cloud, *outputs.cloud, prepared);
    checkScan(outputs.scan, params);
  } catch (const core::MotionUnavailable&) {  // TfGapTooLong included
    if (coverage == 0 && !use_tf &&
        (params.max_tf_gap == 0.0 || step <= core::secondsToNs(params.max_tf_gap)))
      std::abort();  // the samples covered the sweep, without a gap
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* bytes, size_t size) {
  if (size == 0)
    return 0;
  FuzzedDataProvider data(bytes + 1, size - 1);
  const ros_adapter::DeskewParams params = drawParams(data);
  const bool use_tf = data.ConsumeBool();
  const int coverage = data.ConsumeIntegralInRange<int>(0, 2);
  sensor_msgs::PointCloud2::Ptr cloud;
  if (bytes[0] % 2 == 0) {
    cloud = deserializeCloud(data.ConsumeRemainingBytes<std::uint8_t>());
    if (cloud == nullptr || cloud->data.size() > (1u << 22))
      return 0;
  } else {
    cloud = buildCloud(data);
  }
  process(cloud, params, use_tf, coverage);
  return 0;
}
