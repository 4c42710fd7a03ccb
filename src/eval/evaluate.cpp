#include "lidar_deskew/eval/evaluate.h"

#include <laser_geometry/laser_geometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2/exceptions.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/bag_file.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::eval {
namespace {

using ros_adapter::fromMsg;

Eigen::Vector2d polarPoint(double range, double angle) {
  return range * Eigen::Vector2d(std::cos(angle), std::sin(angle));
}

/// Everything a figure shows of one scan, in the laser frame at its reference time.
void writeFigureCsv(const std::string& path, const sim::Truth& truth, const core::PlanarScan& scan,
                    const core::BeamTiming& timing, const core::DeskewedScan& corrected,
                    const core::RebinnedScan& rebinned,
                    const std::vector<Eigen::Vector2d>& laser_geometry_world) {
  std::ofstream out(path);
  if (!out)
    throw std::runtime_error("cannot write " + path);
  const sim::Pose2 reference_laser = truth.laserPose(corrected.reference_time);
  out << "kind,x,y,x2,y2\n";
  for (const sim::Segment& wall : truth.world.segments()) {
    const Eigen::Vector2d a = reference_laser.applyInverse(wall.a), b = reference_laser.applyInverse(wall.b);
    out << "wall," << a.x() << "," << a.y() << "," << b.x() << "," << b.y() << "\n";
  }
  for (int k = 0; k <= 40; ++k) {  // the laser's path during the sweep
    const core::TimeNs time =
        timing.earliestBeamTime() + (timing.latestBeamTime() - timing.earliestBeamTime()) * k / 40;
    const sim::Pose2 laser = truth.laserPose(time);
    const Eigen::Vector2d p = reference_laser.applyInverse({laser.x, laser.y});
    out << "path," << p.x() << "," << p.y() << ",,\n";
  }
  const core::ReturnTest is_return(scan);
  for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!is_return(scan.ranges[i]))
      continue;
    const Eigen::Vector2d p =
        polarPoint(scan.ranges[i], scan.angle_min + i * static_cast<double>(scan.angle_increment));
    out << "raw," << p.x() << "," << p.y() << ",,\n";
  }
  for (const core::DeskewedPoint& point : corrected.points) {
    out << "corrected," << point.position.x() << "," << point.position.y() << ",,\n";
  }
  for (std::size_t b = 0; b < rebinned.ranges.size(); ++b) {
    if (!std::isfinite(rebinned.ranges[b]))
      continue;
    const Eigen::Vector2d p =
        polarPoint(rebinned.ranges[b], scan.angle_min + b * static_cast<double>(scan.angle_increment));
    out << "scan," << p.x() << "," << p.y() << ",,\n";
  }
  for (const Eigen::Vector2d& world_point : laser_geometry_world) {
    const Eigen::Vector2d p = reference_laser.applyInverse(world_point);
    out << "laser_geometry," << p.x() << "," << p.y() << ",,\n";
  }
}

}  // namespace

Evaluation evaluateBag(const std::string& bag_path, const std::string& truth_path,
                       const EvaluateOptions& options) {
  const sim::Truth truth = sim::readTruth(truth_path);
  // All of the bag's tf in one buffer (the bag is short), so every scan's sweep is covered; read the
  // way deskew_bag reads it.
  rosbag::Bag bag = ros_adapter::openBagForReading(bag_path);
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      loadRecordedTf(bag, bag_path, options.fixed_frame, options.base_frame, nullptr, {options.scan_topic});
  std::vector<sensor_msgs::LaserScan::ConstPtr> scans;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(options.scan_topic))) {
    if (auto scan = message.instantiate<sensor_msgs::LaserScan>())
      scans.push_back(scan);
  }
  if (scans.empty())
    throw std::runtime_error(bag_path + " has no LaserScan on " + options.scan_topic);

  Evaluation evaluation;
  evaluation.scenario = truth.scenario;
  evaluation.scans = scans.size();
  evaluation.range_sigma_mm = 1e3 * truth.range_sigma;
  core::ScanDeskewer deskewer(options.deskew);
  core::ScanRebinner rebinner(options.rebin), truth_rebinner(options.rebin);
  core::DeskewedScan truth_corrected;
  core::RebinnedScan truth_rebinned;
  laser_geometry::LaserProjection projector;
  std::vector<double> raw, cloud, rebinned_scan, laser_geometry_errors, to_hit;
  double noise_sum_squares = 0.0;
  std::size_t noise_count = 0;

  for (std::size_t k = 0; k < scans.size(); ++k) {
    const sensor_msgs::LaserScan& message = *scans[k];
    const core::PlanarScan scan = fromMsg(message);
    const core::BeamTiming timing = core::resolveTiming(scan, options.timing);
    mrpt::poses::CPose3D mount;
    core::DeskewedScan corrected;
    sensor_msgs::PointCloud2 projected;
    try {
      std::string error;
      const auto laser_mount = tf->mount(ros_adapter::normalizedFrame(message.header.frame_id),
                                         timing.latestBeamTime(), error);  // in force at the sweep's end
      if (!laser_mount)
        throw std::runtime_error("no laser mount: " + error);
      mount = *laser_mount;
      deskewer.deskew(scan, timing, mount, tf->motion(), corrected);
      projector.transformLaserScanToPointCloud(message.header.frame_id, message, projected,
                                               options.fixed_frame, tf->buffer(), -1.0,
                                               laser_geometry::channel_option::Index);
    } catch (const core::MotionUnavailable&) {
      ++evaluation.left_out;  // tf does not cover the sweep (the recording's edges): left out, counted
      continue;
    } catch (const tf2::TransformException&) {
      ++evaluation.left_out;  // ... nor laser_geometry's lookups
      continue;
    } catch (const std::exception& error) {
      throw std::runtime_error(bag_path + ": scan " + std::to_string(k) + ": " + error.what());
    }
    core::RebinnedScan rebinned;
    rebinner.rebin(corrected, {scan.angle_min, scan.angle_increment, scan.ranges.size()},
                   core::noReturnValue(scan), rebinned);

    const sim::Pose2 laser_at_stamp = truth.laserPose(scan.stamp);
    const sim::Pose2 laser_at_reference = truth.laserPose(corrected.reference_time);
    const core::ReturnTest is_return(scan);
    truth_corrected.reference_time = corrected.reference_time;
    truth_corrected.has_intensities = corrected.has_intensities;
    truth_corrected.points.clear();
    for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
      if (!is_return(scan.ranges[i]))
        continue;
      const double angle = scan.angle_min + i * static_cast<double>(scan.angle_increment);
      raw.push_back(truth.world.distanceTo(laser_at_stamp.apply(polarPoint(scan.ranges[i], angle))));
    }
    for (const core::DeskewedPoint& point : corrected.points) {
      const Eigen::Vector2d world_point = laser_at_reference.apply(point.position.head<2>());
      cloud.push_back(truth.world.distanceTo(world_point));
      // The beam's own true hit, cast again from the true laser pose at the beam's time.
      const sim::Pose2 laser = truth.laserPose(timing.beamTime(point.beam_index));
      const double angle =
          laser.yaw + scan.angle_min + point.beam_index * static_cast<double>(scan.angle_increment);
      const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
      if (const auto hit = truth.world.castRayHit({laser.x, laser.y}, direction)) {
        const Eigen::Vector2d true_hit = Eigen::Vector2d(laser.x, laser.y) + hit->range * direction;
        to_hit.push_back((world_point - true_hit).norm());
        core::DeskewedPoint truth_point = point;
        truth_point.position.head<2>() = laser_at_reference.applyInverse(true_hit);
        truth_point.position.z() = 0.0;
        truth_corrected.points.push_back(truth_point);
        const double cosine = direction.dot(hit->normal);
        noise_sum_squares += truth.range_sigma * truth.range_sigma * cosine * cosine;
        ++noise_count;
      }
    }
    truth_rebinner.rebin(truth_corrected, {scan.angle_min, scan.angle_increment, scan.ranges.size()},
                         core::noReturnValue(scan), truth_rebinned);
    for (std::size_t b = 0; b < rebinned.ranges.size(); ++b) {
      const bool ours = std::isfinite(rebinned.ranges[b]) && is_return(rebinned.ranges[b]);
      if (std::isfinite(truth_rebinned.ranges[b]) && is_return(truth_rebinned.ranges[b])) {
        ++evaluation.truth_scan_filled;
        evaluation.scan_emptied += !ours;
      }
      if (!ours)
        continue;
      const double angle = scan.angle_min + b * static_cast<double>(scan.angle_increment);
      rebinned_scan.push_back(
          truth.world.distanceTo(laser_at_reference.apply(polarPoint(rebinned.ranges[b], angle))));
      evaluation.scan_over_1cm += rebinned_scan.back() > 0.01;
    }
    std::vector<Eigen::Vector2d> laser_geometry_world;
    for (sensor_msgs::PointCloud2ConstIterator<float> x(projected, "x"), y(projected, "y"); x != x.end();
         ++x, ++y) {
      laser_geometry_world.push_back(laser_at_stamp.apply({*x, *y}));
      laser_geometry_errors.push_back(truth.world.distanceTo(laser_geometry_world.back()));
    }
    if (!options.figure_csv.empty() && k == std::min(options.figure_scan, scans.size() - 1)) {
      writeFigureCsv(options.figure_csv, truth, scan, timing, corrected, rebinned, laser_geometry_world);
    }
  }
  evaluation.scans = scans.size() - evaluation.left_out;
  if (evaluation.scans == 0)
    throw std::runtime_error(bag_path + ": tf covers none of the " + std::to_string(scans.size()) + " scans");
  evaluation.raw = sim::errorStats(raw).scaled(1e3);
  evaluation.cloud = sim::errorStats(cloud).scaled(1e3);
  evaluation.scan = sim::errorStats(rebinned_scan).scaled(1e3);
  evaluation.laser_geometry = sim::errorStats(laser_geometry_errors).scaled(1e3);
  evaluation.cloud_to_hit = sim::errorStats(to_hit).scaled(1e3);
  evaluation.noise_only_rms = noise_count ? 1e3 * std::sqrt(noise_sum_squares / noise_count) : 0.0;
  return evaluation;
}

}  // namespace lidar_deskew::eval
