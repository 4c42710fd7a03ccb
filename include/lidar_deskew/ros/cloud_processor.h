// From a PointCloud2 with per-point times to the deskewed PointCloud2: the one code path of the cloud
// nodelet and deskew_bag --cloud-topic (docs/DESIGN.md §7).
#pragma once

#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/ros/cloud_timing.h"
#include "lidar_deskew/ros/deskew_params.h"

namespace lidar_deskew::ros_adapter {

/// A cloud checked and timed, ready to be corrected once its motion is known.
struct PreparedCloud {
  sensor_msgs::PointCloud2::ConstPtr message;
  /// How its times were read; with azimuth timing, name "" (no field to rewrite) and seconds from the
  /// stamp.
  CloudTimeField time_field;
  /// [m] The returns (finite coordinates, not at the origin), in the cloud's order.
  std::vector<Eigen::Vector3d> points;
  std::vector<std::uint32_t> byte_offsets;  ///< where each return starts in message->data
  /// The returns grouped by time (a multi-line LIDAR's column fires at once), offsets from `first`.
  core::Firings firings;
  std::vector<core::TimeNs> firing_times;  ///< [ns] of each firing, exact
  core::TimeNs first = 0;                  ///< [ns] earliest return (header.stamp when none)
  core::TimeNs last = 0;                   ///< [ns] latest return

  /// Timed by azimuth_timing (no time field).
  bool byAzimuth() const { return time_field.name.empty(); }
  /// [ns] Return i's time.
  core::TimeNs timeOf(std::size_t i) const { return firing_times[firings.of_point[i]]; }
  core::TimeNs earliest() const { return first; }
  core::TimeNs latest() const { return last; }
  /// How the cloud was timed, for the log: "point times from field t (uint32, ns, from header.stamp)".
  std::string timingFound() const {
    return byAzimuth() ? "point times from the azimuth (no time field)" : "point times from field " + time_field.describe();
  }
  /// How the cloud was timed, when not by its own time field.
  const char* timingFallback() const {
    return byAzimuth() ? "clouds have no time field; point times come from their azimuth (azimuth_timing)"
                       : nullptr;
  }
};

/// The output of one cloud.
struct CloudOutputs {
  sensor_msgs::PointCloud2::ConstPtr cloud;  ///< every input field and its layout; stamped at the reference
  /// With cloud_scan: the points within the height band as a planar LaserScan (nearest per bin), in the
  /// cloud's frame and stamp, with each kept point's `intensity` field as its intensity when the cloud
  /// has one (intensities empty otherwise; 0 in bins without a point); null without cloud_scan.
  sensor_msgs::LaserScan::ConstPtr scan;
};

/// Corrects clouds with the core. The output keeps every field and the layout of the input: x y z of
/// each return replaced by its position in the input's frame at the reference time; the time field of
/// each return rewritten to the time its position now holds (0 from the stamp, or the reference time
/// when absolute), so a consumer that deskews by that field does not correct it twice. A `range` field
/// (Ouster's, uint32 mm) is scaled by how much farther from the sensor the corrected position lies
/// than the raw one, so it stays the distance of x y z in the driver's own unit. Points that are
/// no return (a non-finite coordinate, or exactly the origin: "no return" for Ouster and others) are
/// left as they were: an organized cloud keeps its shape. Not thread-safe.
class CloudProcessor {
 public:
  using Message = sensor_msgs::PointCloud2;
  static constexpr const char* kNoun = "cloud";  ///< what logs and diagnostics call one message
  using Prepared = PreparedCloud;
  using Outputs = CloudOutputs;

  explicit CloudProcessor(const DeskewParams& params);

  /// Checks a cloud and reads every point's time, in one pass over its data. Throws core::InvalidInput
  /// naming the bad field (the time field, when none is found or its values fit no unit: the message
  /// names the cloud's fields; with azimuth_timing, a cloud without one is timed by azimuth instead).
  PreparedCloud prepare(const sensor_msgs::PointCloud2::ConstPtr& message) const;
  /// Throws core::MotionUnavailable when the motion does not cover the sweep, TfGapTooLong when it has
  /// a gap longer than max_tf_gap there.
  CloudOutputs correct(const PreparedCloud& prepared, const mrpt::poses::CPose3D& mount,
                       const core::MotionSource& motion);
  /// The input itself (on_tf_failure: pass_through).
  CloudOutputs passThrough(const PreparedCloud& prepared) const;

 private:
  /// The planar scan of the finite `points` (the returns of `prepared`, in its order: raw or corrected)
  /// within the height band (nearest per bin), with the intensities of `prepared`'s intensity field.
  sensor_msgs::LaserScan::ConstPtr planarScan(const std::vector<Eigen::Vector3d>& points,
                                              const PreparedCloud& prepared,
                                              const std_msgs::Header& header) const;

  DeskewParams params_;
  CloudTimeConfig time_config_;
  core::TimeNs time_offset_;  ///< [ns] the time_offset parameter, added to every point's time
  core::ScanDeskewer deskewer_;
  /// The corrected returns of a block (with cloud_scan, of the whole cloud: the scan reads them).
  std::vector<Eigen::Vector3d> corrected_;
};

}  // namespace lidar_deskew::ros_adapter
