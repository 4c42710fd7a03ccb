// A small planar LIDAR simulator with closed-form truth, ROS-free. It shares no geometry code with the
// correction (plain 2D trigonometry, no MRPT), so tests that compare the two are independent.
#pragma once

#include <Eigen/Core>

#include <optional>
#include <random>
#include <string>
#include <vector>

#include "lidar_deskew/core/scan.h"

namespace lidar_deskew::sim {

/// RMS, 95th percentile and maximum of non-negative errors, in the input's unit, and their count.
struct ErrorStats {
  double rms = 0.0;
  double p95 = 0.0;
  double max = 0.0;
  std::size_t count = 0;

  /// The same statistics in another unit (e.g. 1e3 for metres -> millimetres).
  ErrorStats scaled(double factor) const { return {rms * factor, p95 * factor, max * factor, count}; }
};
ErrorStats errorStats(std::vector<double> errors);

/// A planar pose: position [m] and heading [rad].
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double yaw = 0.0;

  /// This pose followed by `local` (local expressed in this pose's frame).
  Pose2 compose(const Pose2& local) const;
  /// A point given in this pose's frame, in the parent frame.
  Eigen::Vector2d apply(const Eigen::Vector2d& local) const;
  /// A point given in the parent frame, in this pose's frame.
  Eigen::Vector2d applyInverse(const Eigen::Vector2d& global) const;
  /// `later` in this pose's frame: this^-1 (+) later, its yaw difference wrapped to [-pi, pi].
  Pose2 between(const Pose2& later) const;
};

/// A wall: the line segment from a to b [m].
struct Segment {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

/// Where the ray origin + r direction crosses `segment`: r (in units of |direction|), if it does at
/// r > 0 (a ray parallel to the segment never does).
std::optional<double> raySegmentRange(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction,
                                      const Segment& segment);
/// Distance [m] from `point` to the nearest point of `segment`.
double distanceToSegment(const Eigen::Vector2d& point, const Segment& segment);

/// A 2D world of line segments.
class World {
 public:
  void add(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { segments_.push_back({a, b}); }
  /// A closed polygon through `corners`.
  void addPolygon(const std::vector<Eigen::Vector2d>& corners);
  /// A closed polygon through `corners` that is the world's outer boundary: added like addPolygon
  /// and kept as outline() (a world has at most one; a later call replaces the outline kept).
  void addOutline(const std::vector<Eigen::Vector2d>& corners);
  const std::vector<Segment>& segments() const { return segments_; }
  /// The outer boundary given to addOutline, counter-clockwise; empty if there is none.
  const std::vector<Eigen::Vector2d>& outline() const { return outline_; }
  /// Whether `point` lies inside outline() (false without one). Obstacles inside it do not count.
  bool insideOutline(const Eigen::Vector2d& point) const;

  /// Where a ray meets the nearest wall: distance [m] along the unit ray, and the wall's unit normal.
  struct Hit {
    double range;
    Eigen::Vector2d normal;
  };
  std::optional<Hit> castRayHit(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction) const;
  /// Distance [m] along the unit ray from `origin` to the nearest wall, if any is hit.
  std::optional<double> castRay(const Eigen::Vector2d& origin, const Eigen::Vector2d& direction) const;
  /// Distance [m] from `point` to the nearest wall (infinity for an empty world).
  double distanceTo(const Eigen::Vector2d& point) const;

  /// A 12 x 8 m room centred on the origin, with a slanted wall across one corner and a 0.4 m pillar.
  static World demoRoom();
  /// The paper experiments' world: a 40 x 10 m hall (x from -20 to 20 m) with walls at several angles,
  /// pillars and a 2.4 m wide corridor leaving it, so a robot can drive 8 m at 6 m/s in it.
  static World hall();
  /// The hall's outer walls as one closed polygon, counter-clockwise (its first segments).
  static std::vector<Eigen::Vector2d> hallOutline();
  /// A 5 x 4 m room (x from -2.5 to 2.5 m, y from -2 to 2 m) for short-range sensors such as the
  /// LDS-01 (3.5 m): from anywhere near its middle every wall is within 3.5 m. The north-east corner is
  /// cut by a wall at 45 deg, a wall at about 32 deg stands across the south-east corner, and a 0.3 m
  /// box stands 0.3 m from the west wall.
  static World smallRoom();
  /// The small room's outer walls as one closed polygon, counter-clockwise (its first segments).
  static std::vector<Eigen::Vector2d> smallRoomOutline();

 private:
  std::vector<Segment> segments_;
  std::vector<Eigen::Vector2d> outline_;
};

/// Base pose in the world at time t [s].
class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual Pose2 pose(double t) const = 0;
};

/// A unicycle from `start` after `t` [s] with forward speed `speed + acceleration * t` [m/s] and a
/// constant yaw rate [rad/s], integrated in closed form (exact: no numerical integration).
Pose2 integrateUnicycle(const Pose2& start, double speed, double acceleration, double yaw_rate, double t);

/// Constant forward speed v [m/s] and yaw rate w [rad/s] from `start` at t = 0: an arc (a line for
/// w = 0, a spin in place for v = 0), integrated in closed form.
class ArcTrajectory final : public Trajectory {
 public:
  ArcTrajectory(const Pose2& start, double speed, double yaw_rate)
      : start_(start), speed_(speed), yaw_rate_(yaw_rate) {}
  Pose2 pose(double t) const override { return integrateUnicycle(start_, speed_, 0.0, yaw_rate_, t); }

 private:
  Pose2 start_;
  double speed_;
  double yaw_rate_;
};

/// One piece of a piecewise motion: for `duration` [s], forward speed starting at `speed` [m/s] and
/// changing by `acceleration` [m/s^2], at a constant `yaw_rate` [rad/s].
struct MotionPiece {
  double duration = 0.0;
  double speed = 0.0;
  double acceleration = 0.0;
  double yaw_rate = 0.0;
};

/// Pieces of unicycle motion one after the other from `start` at t = 0, each integrated exactly; the
/// last piece goes on past its duration. Before t = 0 the first piece runs backwards in time.
class PiecewiseTrajectory final : public Trajectory {
 public:
  PiecewiseTrajectory(const Pose2& start, std::vector<MotionPiece> pieces);
  Pose2 pose(double t) const override;
  /// Forward speed [m/s] and yaw rate [rad/s] at time t [s].
  double speed(double t) const;
  double yawRate(double t) const { return pieces_[pieceAt(t)].yaw_rate; }
  const std::vector<MotionPiece>& pieces() const { return pieces_; }
  const Pose2& start() const { return starts_.front(); }

 private:
  std::size_t pieceAt(double t) const;

  std::vector<MotionPiece> pieces_;
  std::vector<Pose2> starts_;        // pose at the start of each piece
  std::vector<double> begin_times_;  // [s]
};

/// A unicycle whose twist changes smoothly all the time, between any odometry samples: forward speed
/// speed * cos(2 pi t / speed_period) [m/s] (through zero into reverse and back) and yaw rate
/// yaw_rate * cos(2 pi t / turn_period) [rad/s], both at their peak with zero slope at t = 0. As pieces
/// of `piece` [s] covering [0, duration] (PiecewiseTrajectory): each piece's speed ramps linearly between
/// the cosine's values at its ends and its yaw rate is the cosine's mean over it, so the heading is
/// exact at every piece's end and within a piece off the smooth motion by at most
/// |yaw_rate'| piece^2 / 8 (2e-7 rad at 5 rad/s, period 1.3 s, 0.25 ms). Before t = 0 the first piece
/// runs backwards (about constant twist, which continues the motion with its first derivative).
std::vector<MotionPiece> smoothUnicyclePieces(double speed, double yaw_rate, double duration,
                                              double speed_period = 2.0, double turn_period = 1.3,
                                              double piece = 2.5e-4);

/// Wheel odometry of a robot driving `truth`: the true motion integrated with a relative error per
/// step (encoder quantisation, slip), so that it walks away from the truth at random.
///
/// The model: steps of kStepDuration (20 ms) on a fixed grid s_j = begin_time + j * kStepDuration.
/// Step j's true body-frame increment is the relative pose d_j = truth(s_j)^-1 (+) truth(s_j+1) =
/// (dx, dy, dyaw); the odometry measures it as (dx f_x, dy f_y, dyaw f_yaw) with the step's factors
/// f = 1 + relative_noise * n, n ~ N(0, 1) independent per step and per component (drawn from
/// std::mt19937(seed), x then y then yaw, step after step). The odometry starts at the true pose at
/// begin_time and composes the measured increments: odom(s_j+1) = odom(s_j) (+) measured d_j. Between
/// grid points, for t in [s_j, s_j+1): odom(t) = odom(s_j) (+) (truth(s_j)^-1 (+) truth(t)) scaled by
/// step j's factors. With relative_noise 0 (and yaw_scale 1) the odometry is the truth: pose(t) is
/// truth.pose(t), bit for bit. `yaw_scale` multiplies every step's yaw factor: odometry that reports
/// that share of the true rotation (a wrong wheel base), with or without noise. `truth` must outlive
/// this object.
class NoisyOdometry final : public Trajectory {
 public:
  static constexpr double kStepDuration = 0.02;  ///< [s]

  /// The factors (1 + relative_noise * n) of one step.
  struct Factors {
    double x = 1.0;
    double y = 1.0;
    double yaw = 1.0;
  };

  /// Odometry over [begin_time, end_time] [s] (whole steps: up to the first grid point at or after
  /// end_time). Throws std::invalid_argument if relative_noise is negative or not finite, yaw_scale not
  /// positive and finite, or the times are not finite or end_time < begin_time.
  NoisyOdometry(const Trajectory& truth, double begin_time, double end_time, double relative_noise,
                unsigned seed, double yaw_scale = 1.0);
  /// The odometry's pose at t [s]; throws std::out_of_range outside the steps.
  Pose2 pose(double t) const override;
  /// The factors of the step that holds t [s] (all 1 without noise); throws like pose().
  Factors factors(double t) const;
  /// [s] start of step j.
  double stepStart(std::size_t j) const { return begin_time_ + static_cast<double>(j) * kStepDuration; }
  std::size_t steps() const { return factors_.size(); }

 private:
  std::size_t stepAt(double t) const;
  /// odom(s_j) (+) the increment from truth(s_j) to `true_pose`, scaled by step j's factors.
  Pose2 measured(std::size_t j, const Pose2& true_pose) const;

  const Trajectory& truth_;
  double begin_time_;
  double relative_noise_;
  double yaw_scale_;
  std::vector<Factors> factors_;      // per step
  std::vector<Pose2> step_truth_;     // truth(s_j)
  std::vector<Pose2> step_odometry_;  // odom(s_j)
};

/// A rotating 2D LIDAR. Beams are evenly spaced in angle and in time: one revolution per scan period.
struct LidarModel {
  std::string name;
  int beams = 360;
  double field_of_view = 2.0 * M_PI;  ///< [rad] beams * |increment|
  double rate = 10.0;                 ///< [Hz] scans per second (revolutions per second)
  double range_sigma = 0.0;           ///< [m] Gaussian range noise (used when noise is on)
  bool clockwise = false;             ///< angle_increment < 0
  float range_min = 0.05f;            ///< [m]
  float range_max = 30.0f;            ///< [m]

  float angleIncrement() const;  ///< [rad], signed
  float angleMin() const;        ///< [rad] first beam: -fov/2 (counter-clockwise) or +fov/2 (clockwise)
  float timeIncrement() const;   ///< [s] revolution time * |increment| / 2pi
  /// [s] from the first beam to the last: (beams - 1) * timeIncrement() (the float, as a double).
  double sweepDuration() const;

  /// Paper Table 1 / 2: Hokuyo UTM-30LX 1440 beams 360 deg 40 Hz sigma 30 mm; Inmotion ILD26TRI
  /// 360 beams 360 deg 8 Hz sigma 60 mm; UTM-30LX 1080 beams 270 deg 40 Hz sigma 30 mm.
  static LidarModel utm30lx360();
  static LidarModel ild26tri();
  static LidarModel utm30lx270();
  /// A TurtleBot3's LDS-01 (HLS-LFCD-LDS): 360 beams over 360 deg (1 deg steps), 5 Hz (300 rpm),
  /// counter-clockwise, range 0.12 to 3.5 m, sigma 15 mm (the data sheet's accuracy at short range).
  static LidarModel lds01();
};

/// How a LaserScan message gets its sensor's timing wrong: what deskew_calibrate estimates and the
/// node's time_offset, beam order and scan_period parameters correct (docs/DESIGN.md time
/// conventions). The default is no fault: the message tells the truth.
struct TimingFault {
  /// [s] header.stamp = true time of the earliest beam + stamp_error. The correcting parameter is
  /// time_offset = -stamp_error (true first-beam time = stamp + time_offset).
  double stamp_error = 0.0;
  /// The beams' time order is the reverse of their index order: beam i (at angle angle_min +
  /// i * angle_increment, as the message says) is measured at t0 + (n - 1 - i) * dt, so the earliest
  /// beam is index n - 1. The message still claims index order (time_increment > 0).
  bool reversed = false;
  /// The message's time_increment = factor * the true beam period (0: "unknown").
  double time_increment_factor = 1.0;
  /// The message's scan_time = 0 (with time_increment_factor 0 the message tells no period at all).
  bool zero_scan_time = false;

  /// Whether the message tells anything but the truth.
  bool any() const {
    return stamp_error != 0.0 || reversed || time_increment_factor != 1.0 || zero_scan_time;
  }
  /// Throws std::invalid_argument naming the field if stamp_error or time_increment_factor is not
  /// finite or time_increment_factor is negative.
  void validate() const;
  /// A driver that stamps the scan with its latest beam's time: stamp_error = model.sweepDuration().
  static TimingFault stampedAtEnd(const LidarModel& model);
};

/// One simulated scan and its truth.
struct SimulatedScan {
  core::PlanarScan scan;                    ///< as the driver publishes it (with the TimingFault's errors)
  std::vector<double> beam_times;           ///< [s] true time of every beam, by index (since epoch)
  std::vector<Eigen::Vector2d> world_hits;  ///< [m] true hit point per beam (NaN where no hit)
};

/// Casts every beam from the laser's true pose at that beam's own time: laser = base(t) (+) mount.
/// `start_time` [s] is the earliest beam's true time; without a fault that is beam 0 and the scan is
/// stamped `epoch + start_time`. Beam i is truly measured at start_time + i * dt (dt =
/// model.timeIncrement()), or at start_time + (n - 1 - i) * dt if `fault.reversed`; the message's
/// stamp, time_increment and scan_time carry `fault`'s errors (see TimingFault).
/// `noise`: Gaussian range noise of model.range_sigma when given; exact ranges when null.
/// Beams with no hit within range_max get +inf. Throws std::invalid_argument for an invalid fault.
SimulatedScan simulateScan(const World& world, const Trajectory& trajectory, const Pose2& mount,
                           const LidarModel& model, core::TimeNs epoch, double start_time,
                           std::mt19937* noise = nullptr, const TimingFault& fault = TimingFault());

}  // namespace lidar_deskew::sim
