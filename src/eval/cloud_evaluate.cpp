#include "lidar_deskew/eval/cloud_evaluate.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <tf2/exceptions.h>

#include <memory>
#include <stdexcept>

#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/eval/recorded_tf.h"
#include "lidar_deskew/ros/cloud_processor.h"
#include "lidar_deskew/ros/conversions.h"
#include "lidar_deskew/sim/cloud_scenario.h"

namespace lidar_deskew::eval {
namespace {

/// The returns of a cloud written by CloudProcessor (x y z at their fields), as doubles.
std::vector<Eigen::Vector3d> returnsOf(const ros_adapter::PreparedCloud& prepared) {
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& p : prepared.points) {
    if (p.allFinite())
      points.push_back(p);
  }
  return points;
}

void addDistances(const sim::World3& world, const sim::Pose3& pose,
                  const std::vector<Eigen::Vector3d>& points, std::vector<double>& into) {
  for (double d : sim::distancesToWorld(world, pose, points))
    into.push_back(1e3 * d);
}

/// The returns of `prepared` moved to the reference time with the true sensor motion: point i, measured
/// in the sensor frame at its own time, seen from the true sensor pose at the reference time.
std::vector<Eigen::Vector3d> truthCorrected(const ros_adapter::PreparedCloud& prepared,
                                            const sim::CloudTruth& truth, const sim::Pose3& reference) {
  const sim::Pose3 to_reference = reference.inverse();
  // Built once: a smooth drive has thousands of pieces, and an organized cloud's row-major points
  // change their time at every point.
  const std::shared_ptr<const sim::Trajectory3> trajectory = truth.trajectory();
  std::vector<Eigen::Vector3d> points;
  points.reserve(prepared.points.size());
  core::TimeNs pose_time = 0;
  sim::Pose3 relative;  // reference^-1 (+) sensor(pose_time); a column's points share their time
  bool have_pose = false;
  for (std::size_t i = 0; i < prepared.points.size(); ++i) {
    const Eigen::Vector3d& p = prepared.points[i];
    if (!p.allFinite())
      continue;
    if (!have_pose || prepared.timeOf(i) != pose_time) {
      pose_time = prepared.timeOf(i);
      relative = to_reference.compose(
          trajectory->pose(core::nsToSeconds(pose_time - truth.epoch)).compose(truth.mount));
      have_pose = true;
    }
    points.push_back(relative.apply(p));
  }
  return points;
}

}  // namespace

CloudEvaluation evaluateCloudBag(const std::string& bag_path, const std::string& truth_path,
                                 const std::string& cloud_topic, const ros_adapter::DeskewParams& params,
                                 CloudColumns columns) {
  const bool all = columns == CloudColumns::kAll;
  const sim::CloudTruth truth = sim::readCloudTruth(truth_path);
  const sim::World3 world = sim::World3::byName(truth.world);
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  const std::unique_ptr<ros_adapter::TfFeed> tf =
      loadRecordedTf(bag, bag_path, params.fixed_frame, params.base_frame);

  ros_adapter::CloudProcessor ours(params);
  ros_adapter::DeskewParams exact_params = params;
  exact_params.exact = true;
  exact_params.deskew.knot_interval = 0.0;
  ros_adapter::CloudProcessor per_point(exact_params);

  CloudEvaluation evaluation;
  evaluation.scenario = truth.scenario;
  evaluation.convention = truth.convention;
  evaluation.range_sigma_mm = 1e3 * truth.range_sigma;
  std::vector<double> raw, two_pose, corrected, exact, noise_floor;
  for (const rosbag::MessageInstance& message : rosbag::View(bag, rosbag::TopicQuery(cloud_topic))) {
    const auto cloud = message.instantiate<sensor_msgs::PointCloud2>();
    if (!cloud)
      continue;
    const ros_adapter::PreparedCloud prepared = ours.prepare(cloud);
    std::string error;
    const std::optional<mrpt::poses::CPose3D> mount =
        tf->mount(ros_adapter::normalizedFrame(cloud->header.frame_id), prepared.last, error);
    if (!mount)
      throw std::runtime_error(bag_path + ": no mount: " + error);
    const sim::Pose3 reference = truth.sensorPose(prepared.first);
    std::vector<ros_adapter::PreparedCloud> corrected_clouds;  // ours, per point
    mrpt::poses::CPose3D first, last;
    try {
      for (ros_adapter::CloudProcessor* processor : {&ours, &per_point}) {
        if (processor == &ours || all) {
          const ros_adapter::CloudOutputs out = processor->correct(prepared, *mount, tf->motion());
          corrected_clouds.push_back(ours.prepare(out.cloud));  // reads x y z back
        }
      }
      first = tf->motion().basePose(prepared.first) + *mount;
      last = tf->motion().basePose(prepared.last) + *mount;
    } catch (const core::MotionUnavailable&) {
      ++evaluation.left_out;  // tf does not cover the sweep (the recording's edges): left out, counted
      continue;
    } catch (const tf2::TransformException&) {
      ++evaluation.left_out;
      continue;
    }
    ++evaluation.clouds;

    addDistances(world, reference, returnsOf(corrected_clouds[0]), corrected);
    if (!all)
      continue;
    addDistances(world, reference, returnsOf(prepared), raw);
    addDistances(world, reference, truthCorrected(prepared, truth, reference), noise_floor);
    addDistances(world, reference, returnsOf(corrected_clouds[1]), exact);
    // Constant velocity between the poses at the first and last return (lerp + slerp), composed with MRPT.
    const double span = std::max<double>(1, prepared.last - prepared.first);
    std::vector<Eigen::Vector3d> interpolated;
    for (std::size_t i = 0; i < prepared.points.size(); ++i) {
      const Eigen::Vector3d& p = prepared.points[i];
      if (!p.allFinite())
        continue;
      const mrpt::poses::CPose3D at =
          core::interpolatePose(first, last, static_cast<double>(prepared.timeOf(i) - prepared.first) / span);
      const mrpt::poses::CPose3D relative = at - first;  // the sensor at its time, seen from the first
      mrpt::math::TPoint3D moved;
      relative.composePoint(p.x(), p.y(), p.z(), moved.x, moved.y, moved.z);
      interpolated.emplace_back(moved.x, moved.y, moved.z);
    }
    addDistances(world, reference, interpolated, two_pose);
  }
  if (evaluation.clouds == 0)
    throw std::runtime_error(bag_path + " has no PointCloud2 on " + cloud_topic);
  evaluation.raw = sim::errorStats(raw);
  evaluation.two_pose = sim::errorStats(two_pose);
  evaluation.ours = sim::errorStats(corrected);
  evaluation.per_point = sim::errorStats(exact);
  evaluation.truth_corrected = sim::errorStats(noise_floor);
  return evaluation;
}

}  // namespace lidar_deskew::eval
