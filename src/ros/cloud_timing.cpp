#include "lidar_deskew/ros/cloud_timing.h"

#include <sensor_msgs/PointField.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "lidar_deskew/ros/conversions.h"

namespace lidar_deskew::ros_adapter {

const char* const kTimeFieldNames[6] = {"t", "time", "timestamp", "time_stamp", "offset_time", "stamps"};

namespace {

using sensor_msgs::PointField;

std::string typeName(std::uint8_t datatype) {
  switch (datatype) {
    case PointField::INT8:
      return "int8";
    case PointField::UINT8:
      return "uint8";
    case PointField::INT16:
      return "int16";
    case PointField::UINT16:
      return "uint16";
    case PointField::INT32:
      return "int32";
    case PointField::UINT32:
      return "uint32";
    case PointField::FLOAT32:
      return "float32";
    case PointField::FLOAT64:
      return "float64";
  }
  return "type " + std::to_string(datatype);
}

bool isInteger(std::uint8_t datatype) {
  return datatype != PointField::FLOAT32 && datatype != PointField::FLOAT64;
}

struct Unit {
  const char* name;
  double seconds;
};
constexpr Unit kUnits[] = {{"s", 1.0}, {"ms", 1e-3}, {"us", 1e-6}, {"ns", 1e-9}};

std::string unitName(double seconds) {
  for (const Unit& unit : kUnits) {
    if (unit.seconds == seconds)
      return unit.name;
  }
  return formatNumber(seconds) + " s";
}

/// The units to try, in order of preference for this field.
std::vector<double> candidateUnits(const CloudTimeConfig& config, std::uint8_t datatype) {
  for (const Unit& unit : kUnits) {
    if (config.unit == unit.name)
      return {unit.seconds};
  }
  if (isInteger(datatype))
    return {1e-9, 1e-6, 1e-3, 1.0};
  return {1.0, 1e-3, 1e-6, 1e-9};
}

/// [s] How far beyond its points' offsets a header may lie (a driver's latency).
constexpr double kHeaderSlack = 0.1;

std::string fieldList(const sensor_msgs::PointCloud2& cloud) {
  std::string names;
  for (const PointField& field : cloud.fields)
    names += (names.empty() ? "" : ", ") + field.name + " (" + typeName(field.datatype) + ")";
  return names.empty() ? "none" : names;
}

}  // namespace

void CloudTimeConfig::validate() const {
  if (unit != "auto" && std::none_of(std::begin(kUnits), std::end(kUnits),
                                     [&](const Unit& known) { return unit == known.name; }))
    throw core::InvalidInput("time_unit", "must be one of auto|s|ms|us|ns, got '" + unit + "'");
  if (base != "auto" && base != "header" && base != "absolute")
    throw core::InvalidInput("time_base", "must be one of auto|header|absolute, got '" + base + "'");
}

std::string CloudTimeField::describe() const {
  return name + " (" + typeName(datatype) + ", " + unitName(unit) +
         (absolute ? ", absolute)" : ", from header.stamp)");
}

void checkCloudLayout(const sensor_msgs::PointCloud2& cloud) {
  if (cloud.is_bigendian)
    throw core::InvalidInput("is_bigendian", "big-endian clouds are not supported");
  if (cloud.point_step == 0 && cloud.width * static_cast<std::uint64_t>(cloud.height) > 0)
    throw core::InvalidInput("point_step", "is 0");
  for (const PointField& field : cloud.fields) {
    const std::size_t size = fieldSize(field.datatype);
    if (size == 0)
      throw core::InvalidInput("fields",
                               field.name + " has unknown datatype " + std::to_string(field.datatype));
    if (field.offset + size * std::max<std::uint32_t>(1, field.count) > cloud.point_step)
      throw core::InvalidInput("fields", field.name + " lies outside point_step");
  }
  if (static_cast<std::uint64_t>(cloud.width) * cloud.point_step > cloud.row_step)
    throw core::InvalidInput("row_step", "is less than width x point_step");
  if (static_cast<std::uint64_t>(cloud.height) * cloud.row_step > cloud.data.size())
    throw core::InvalidInput("data", "holds less than height x row_step bytes");
  if (cloud.data.size() > std::numeric_limits<std::uint32_t>::max())
    throw core::InvalidInput("data", "holds more than 4 GiB");
}

std::size_t fieldSize(std::uint8_t datatype) {
  std::size_t size = 0;
  withFieldType(datatype, [&](auto typed) { size = sizeof typed; });
  return size;
}

double readNumber(const std::uint8_t* point, std::uint8_t datatype) {
  double number = std::numeric_limits<double>::quiet_NaN();
  withFieldType(datatype, [&](auto typed) {
    std::memcpy(&typed, point, sizeof typed);
    number = static_cast<double>(typed);
  });
  return number;
}

const PointField* timeFieldOf(const sensor_msgs::PointCloud2& cloud, const CloudTimeConfig& config) {
  const auto rank = [](const std::string& name) {
    return static_cast<std::size_t>(std::find(std::begin(kTimeFieldNames), std::end(kTimeFieldNames), name) -
                                    std::begin(kTimeFieldNames));
  };
  const PointField* found = nullptr;
  for (const PointField& field : cloud.fields) {
    const bool wanted =
        config.field.empty() ? rank(field.name) < std::size(kTimeFieldNames) : field.name == config.field;
    // The first of kTimeFieldNames present wins (a cloud may carry two).
    if (wanted && (found == nullptr || rank(field.name) < rank(found->name)))
      found = &field;
  }
  return found;
}

core::InvalidInput noTimeField(const sensor_msgs::PointCloud2& cloud, const CloudTimeConfig& config) {
  return core::InvalidInput(
      "time field",
      (config.field.empty() ? std::string("none of t, time, timestamp, time_stamp, offset_time, stamps")
                            : "no field '" + config.field + "'") +
          " in the cloud; its fields: " + fieldList(cloud) +
          " (set time_field, or azimuth_timing for a spinning sensor)");
}

CloudTimeField decideTimeField(const PointField& field, double low, double high, core::TimeNs stamp_ns,
                               const CloudTimeConfig& config) {
  CloudTimeField result;
  result.name = field.name;
  result.datatype = field.datatype;
  result.offset = field.offset;
  const bool counted = low <= high;
  if (!counted)
    low = high = 0.0;
  const double stamp = static_cast<double>(stamp_ns) * 1e-9;
  const double sweep = config.max_sweep_duration;
  const std::vector<double> units = candidateUnits(config, result.datatype);

  // Both given: as told, whatever the values (the sweep's span is still checked by the caller).
  if (config.unit != "auto" && config.base != "auto") {
    result.absolute = config.base == "absolute";
    result.unit = units.front();
    return result;
  }
  const auto absolute = [&]() {
    // In some unit, every value within a sweep and a second of the header.
    for (double unit : units) {
      if (counted && std::abs(low * unit - stamp) <= sweep + 1.0 &&
          std::abs(high * unit - stamp) <= sweep + 1.0) {
        result.absolute = true;
        result.unit = unit;
        return true;
      }
    }
    return false;
  };
  const auto relative = [&]() {
    // Offsets from the header: the first unit (integers: ns first; floating: s first) in which the
    // values span at most a sweep, with the header at most 0.1 s
    // beyond them (drivers stamp the first or last point, some with a little latency).
    for (double unit : units) {
      if ((high - low) * unit <= sweep && std::abs(low * unit) <= sweep + kHeaderSlack &&
          std::abs(high * unit) <= sweep + kHeaderSlack) {
        result.absolute = false;
        result.unit = unit;
        return true;
      }
    }
    return false;
  };
  // Near time 0 (a simulator's clock) offsets and times look alike: offsets are the commoner.
  const bool early = stamp <= 2.0 * (sweep + 1.0);
  const bool try_absolute = config.base != "header";
  const bool try_relative = config.base != "absolute";
  if (early ? (try_relative && relative()) || (try_absolute && absolute())
            : (try_absolute && absolute()) || (try_relative && relative()))
    return result;
  throw core::InvalidInput(
      "time field", result.name + " (" + typeName(result.datatype) + ") holds " + formatNumber(low) + " .. " +
                        formatNumber(high) +
                        ": in no unit (s, ms, us, ns) a sweep of at most max_sweep_duration " +
                        formatNumber(sweep) + " s near header.stamp " + std::to_string(stamp) +
                        " (set both time_unit and time_base)");
}

core::TimeNs timeOf(const CloudTimeField& field, core::TimeNs stamp, double value) {
  const core::TimeNs base = field.absolute ? 0 : stamp;
  const auto unit_ns = static_cast<core::TimeNs>(std::llround(field.unit * 1e9));
  // [ns] from the value, whole units and the fraction apart: the conversion adds no error to what the
  // value holds (float64 seconds at epoch-sized times hold about 0.1 us); integers are exact.
  const double whole = std::floor(value);
  return base + static_cast<core::TimeNs>(whole) * unit_ns +
         static_cast<core::TimeNs>(std::llround((value - whole) * static_cast<double>(unit_ns)));
}

namespace {

/// The values of `field` of the points of a cloud that `returns` counts (every point when null), in
/// index order, with their range (low > high when there are none). Throws core::InvalidInput naming
/// the field and the point for a value that is not finite.
std::vector<double> returnValues(const sensor_msgs::PointCloud2& cloud, const PointField& field,
                                 const std::vector<bool>* returns, double& low, double& high) {
  std::vector<double> values;
  low = std::numeric_limits<double>::infinity();
  high = -low;
  const std::size_t count = static_cast<std::size_t>(cloud.width) * cloud.height;
  for (std::size_t i = 0; i < count; ++i) {
    if (returns != nullptr && !(*returns)[i])
      continue;
    const double value = readNumber(&cloud.data[pointOffset(cloud, i) + field.offset], field.datatype);
    if (!std::isfinite(value))
      throw core::InvalidInput("time field",
                               field.name + " of point " + std::to_string(i) + " is not finite");
    values.push_back(value);
    low = std::min(low, value);
    high = std::max(high, value);
  }
  return values;
}

}  // namespace

CloudTimeField findTimeField(const sensor_msgs::PointCloud2& cloud, const CloudTimeConfig& config,
                             const std::vector<bool>* returns) {
  const PointField* field = timeFieldOf(cloud, config);
  if (field == nullptr)
    throw noTimeField(cloud, config);
  double low, high;
  returnValues(cloud, *field, returns, low, high);
  return decideTimeField(*field, low, high, toNs(cloud.header.stamp), config);
}

void pointTimes(const sensor_msgs::PointCloud2& cloud, const CloudTimeField& field,
                std::vector<core::TimeNs>& times, const std::vector<bool>* returns) {
  PointField at;
  at.name = field.name;
  at.offset = field.offset;
  at.datatype = field.datatype;
  double low, high;
  const std::vector<double> values = returnValues(cloud, at, returns, low, high);
  const core::TimeNs stamp = toNs(cloud.header.stamp);
  const std::size_t count = static_cast<std::size_t>(cloud.width) * cloud.height;
  times.assign(count, stamp);  // no return: its time is not read
  for (std::size_t i = 0, k = 0; i < count; ++i) {
    if (returns == nullptr || (*returns)[i])
      times[i] = timeOf(field, stamp, values[k++]);
  }
}

}  // namespace lidar_deskew::ros_adapter
