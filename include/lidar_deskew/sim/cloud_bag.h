// Writes a simulated multi-line LIDAR recording as a ROS 1 bag, the way a real robot records one, in
// the cloud layout of a chosen driver, plus its truth file (cloud_scenario.h).
#pragma once

#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>
#include <vector>

#include "lidar_deskew/sim/cloud_scenario.h"
#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::sim {

/// How a driver lays out a PointCloud2 and stamps it. Every layout has x, y, z float32 at offsets 0, 4, 8
/// in the sensor frame; then, per convention: the per-point time field (type, unit; "rel." = relative to
/// header.stamp), what header.stamp is, the other fields (@ offset) and the point step:
///
/// - kOuster (ouster-ros): `t` uint32 ns rel.; stamp = sweep start (column 0); intensity f32 @16, t @20,
///   reflectivity u16 @24, ring u16 @26, ambient u16 @28, range u32 [mm] @32; 48 B. Organized:
///   height = rings, width = columns, row = ring; no return = all zeros (t and ring still set).
/// - kVelodyneFirst (velodyne_pointcloud): `time` float32 s rel.; stamp = first point; intensity f32
///   @12, ring u16 @16, time @18; 22 B.
/// - kVelodyneLast: as kVelodyneFirst, stamp = last point (times <= 0).
/// - kHesai: `timestamp` float64 s absolute; stamp = first point; intensity f32 @16, timestamp @24,
///   ring u16 @32; 48 B.
/// - kRoboSense (rslidar_sdk): `timestamp` float64 s absolute; stamp = LAST point; intensity f32 @16,
///   ring u16 @20, timestamp @24; 32 B.
/// - kLivox2 (livox_ros_driver2): `timestamp` float64 ns absolute; stamp = first point; intensity f32
///   @12, tag u8 @16, line u8 @17 (= ring), timestamp @18; 26 B.
/// - kAutoware: `time_stamp` uint32 ns rel.; stamp = first point; intensity f32 @12, ring u16 @16,
///   time_stamp @20; 24 B.
/// - kLivoxCustom (a Livox CustomMsg as a cloud): `offset_time` uint32 ns rel.; stamp = first point;
///   reflectivity f32 @12, tag u8 @16, line u8 @17, offset_time @20; 24 B.
/// - kLaserGeometry (projectLaser with timestamps): `stamps` float32 s rel.; stamp = first point;
///   intensity f32 @12, stamps @16; 20 B.
/// - kNoTime (velodyne_pointcloud's PointXYZIR, before it had a time field; or any XYZI cloud): no
///   time field; stamp = first point; intensity f32 @16, ring u16 @20; 32 B. Only azimuth timing can
///   correct it (docs/CLOUDS.md); without it such clouds are dropped with an error naming their fields.
///
/// header.stamp is on whole nanoseconds, rounded down (start, first point) or up (last point), so that
/// relative times never change sign. All but kOuster are dense (height 1, returns only, in firing order),
/// whatever the model's `organized`. Intensity is 100 for a return and 0 for none (the simulator has no
/// reflectance).
enum class CloudConvention {
  kOuster,
  kVelodyneFirst,
  kVelodyneLast,
  kHesai,
  kRoboSense,
  kLivox2,
  kAutoware,
  kLivoxCustom,
  kLaserGeometry,
  kNoTime
};

/// Every convention with a per-point time field, in the enum's order: the drivers' layouts that are
/// corrected with no configuration, which the tests iterate. kNoTime is deliberately not among them (it
/// needs azimuth timing configured).
const std::vector<CloudConvention>& allCloudConventions();
/// The names of allCloudConventions() and then "no_time".
std::vector<std::string> cloudConventionNames();
/// "ouster", "velodyne_first", "velodyne_last", "hesai", "robosense", "livox2", "autoware",
/// "livox_custom", "laser_geometry", "no_time".
std::string cloudConventionName(CloudConvention convention);
/// The convention of that name (cloudConventionNames()); throws std::invalid_argument listing the
/// names otherwise.
CloudConvention cloudConventionFromName(const std::string& name);
/// The name of the per-point time field of the convention ("t", "time", ...); throws
/// std::invalid_argument for kNoTime.
std::string cloudTimeField(CloudConvention convention);
/// Whether the convention's clouds are organized (height = rings).
inline bool isOrganized(CloudConvention convention) {
  return convention == CloudConvention::kOuster;
}

/// The sweep as the driver of `convention` publishes it, in `frame_id`; header.seq = `seq`.
/// Times on the simulation clock are put on the bag clock as epoch + t. An organized convention needs
/// an organized sweep and a dense one a dense sweep (std::invalid_argument otherwise).
sensor_msgs::PointCloud2 toPointCloud2(const SimulatedCloud& sweep, CloudConvention convention,
                                       core::TimeNs epoch, const std::string& frame_id,
                                       std::uint32_t seq = 0);

struct CloudBagOptions {
  CloudConvention convention = CloudConvention::kOuster;
  bool noise = false;      ///< add the LIDAR's Gaussian range noise
  unsigned seed = 1;       ///< of the noise
  double tf_rate = 50.0;   ///< [Hz] of /tf fixed -> base
  double latency = 0.005;  ///< [s] record time = last point's time + latency
  double tf_margin = 0.1;  ///< [s] /tf from this before the first sweep to this after the last
  core::TimeNs epoch = 1'700'000'000'000'000'000;  ///< [ns] bag time of t = 0
  double duration = 0.0;                           ///< [s] > 0: instead of the scenario's
  std::string fixed_frame = "odom";
  std::string base_frame = "base_link";
  std::string lidar_frame = "lidar";
  std::string cloud_topic = "/points";
  /// The odometry as a wheeled robot produces it (none of it by default: /tf is the true pose), as
  /// SimBagOptions' fields of the same names (sim::recordOdometry): relative noise per 20 ms step and
  /// its seed, a yaw scale, and the samples' timing (jitter, irregular rate, encoder ticks, late and
  /// burst recording), in the truth file. Wheels and encoders measure the planar motion only: noise,
  /// scale and ticks act on x, y and yaw, while z, roll and pitch (rough ground) stay the truth at the
  /// sample's time, as from an IMU and a known ground (they do not drift).
  double odom_noise = 0.0;
  unsigned odom_noise_seed = 1;
  double odom_yaw_scale = 1.0;
  OdometryTiming odom_timing;
};

/// `pose` as the tf transform parent -> child at `time` [ns].
geometry_msgs::TransformStamped stamped(const std::string& parent, const std::string& child,
                                        core::TimeNs time, const Pose3& pose);

/// Simulates `scenario` and writes `bag_path` with
/// - /points (sensor_msgs/PointCloud2) in the convention's layout (toPointCloud2), one per sweep,
///   recorded at its last point's time + latency;
/// - /tf (tf2_msgs/TFMessage): fixed -> base at tf_rate, the true 3D pose (perfect odometry) or the
///   odometry the options ask for, from 0.1 s before the first sweep to 0.1 s after the last sweep's
///   end (jitter further out), recorded in time order with the clouds;
/// - /tf_static: base -> lidar (the mount), once, latched (writeTfStatic in sim_bag.h);
/// in time order, and the matching truth file at `truth_path`. Throws on I/O errors, and
/// std::invalid_argument for a bad tf_rate or odometry option.
void writeCloudBag(const CloudScenario& scenario, const CloudBagOptions& options, const std::string& bag_path,
                   const std::string& truth_path);

}  // namespace lidar_deskew::sim
