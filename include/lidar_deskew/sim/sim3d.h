// A small spinning multi-line LIDAR simulator with closed-form truth, ROS-free. Like the planar one
// (sim.h) it shares no geometry code with the correction: plain Eigen, no MRPT, so tests that compare
// the two are independent. Frames follow REP-103: x forward, y left, z up.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::sim {

/// A rigid pose in 3D: position [m] and rotation (child frame axes in the parent frame).
struct Pose3 {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();

  /// From position [m] and roll, pitch, yaw [rad], ROS / REP-103: R = Rz(yaw) Ry(pitch) Rx(roll).
  static Pose3 fromXyzRpy(double x, double y, double z, double roll, double pitch, double yaw);
  /// The planar pose at height z [m].
  static Pose3 fromPose2(const Pose2& pose, double z = 0.0);

  /// This pose followed by `local` (local expressed in this pose's frame).
  Pose3 compose(const Pose3& local) const;
  Pose3 inverse() const;
  /// A point given in this pose's frame, in the parent frame.
  Eigen::Vector3d apply(const Eigen::Vector3d& local) const { return position + rotation * local; }
  /// A point given in the parent frame, in this pose's frame.
  Eigen::Vector3d applyInverse(const Eigen::Vector3d& global) const {
    return rotation.transpose() * (global - position);
  }
  Eigen::Quaterniond quaternion() const { return Eigen::Quaterniond(rotation).normalized(); }
};

/// A 3D world of closed-form surfaces: vertical walls (a 2D segment extruded between two heights),
/// horizontal polygons (floor, ceiling) and vertical cylinders (pillars).
class World3 {
 public:
  struct Wall {
    Eigen::Vector2d a, b;  ///< [m] ends of the footprint
    double z_min, z_max;   ///< [m]
  };
  struct Horizontal {
    std::vector<Eigen::Vector2d> outline;  ///< [m] a simple polygon
    double z;                              ///< [m]
  };
  struct Cylinder {
    Eigen::Vector2d centre;  ///< [m] of the axis
    double radius;           ///< [m]
    double z_min, z_max;     ///< [m]
  };

  explicit World3(std::string name = "") : name_(std::move(name)) {}
  void addWall(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double z_min, double z_max);
  /// Every segment of a planar world as a wall from z_min to z_max [m].
  void addExtruded(const World& plan, double z_min, double z_max);
  void addHorizontal(const std::vector<Eigen::Vector2d>& outline, double z);
  void addCylinder(const Eigen::Vector2d& centre, double radius, double z_min, double z_max);

  /// Distance [m] along the unit ray from `origin` to the nearest surface, if any is hit (only hits at
  /// a distance > 0 count).
  std::optional<double> castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const;
  /// Distance [m] from `point` to the nearest surface (infinity for an empty world).
  double distanceTo(const Eigen::Vector3d& point) const;

  const std::string& name() const { return name_; }
  const std::vector<Wall>& walls() const { return walls_; }
  const std::vector<Horizontal>& horizontals() const { return horizontals_; }
  const std::vector<Cylinder>& cylinders() const { return cylinders_; }

  /// Ceiling height of hall() [m].
  static constexpr double kHallHeight = 3.0;
  /// The planar hall (World::hall(): walls, square pillars, the 30 deg wall) extruded from the floor
  /// (z = 0) to the ceiling (z = 3 m), floor and ceiling bounded by its outline, and three round
  /// pillars (r 0.25-0.4 m) away from the scenarios' paths. Named "hall".
  static World3 hall();
  /// The world of that name ("hall"); throws std::invalid_argument otherwise.
  static World3 byName(const std::string& name);

 private:
  std::string name_;
  std::vector<Wall> walls_;
  std::vector<Horizontal> horizontals_;
  std::vector<Cylinder> cylinders_;
};

/// Base pose in the world at time t [s].
class Trajectory3 {
 public:
  virtual ~Trajectory3() = default;
  virtual Pose3 pose(double t) const = 0;
};

/// A planar trajectory on flat ground: z = 0 (the base at ground level), no roll, no pitch.
class PlanarTrajectory3 final : public Trajectory3 {
 public:
  explicit PlanarTrajectory3(std::shared_ptr<const Trajectory> planar) : planar_(std::move(planar)) {}
  Pose3 pose(double t) const override { return Pose3::fromPose2(planar_->pose(t)); }

 private:
  std::shared_ptr<const Trajectory> planar_;
};

/// How rough ground shakes the base: z, pitch and roll oscillate as A sin(2 pi f t) (zero at t = 0).
/// Defaults: z +-2 cm at 3 Hz, pitch +-2 deg at 2.3 Hz, roll +-1.5 deg at 1.7 Hz.
struct RoughGround {
  double z_amplitude = 0.02;                    ///< [m]
  double z_frequency = 3.0;                     ///< [Hz]
  double pitch_amplitude = 2.0 * M_PI / 180.0;  ///< [rad]
  double pitch_frequency = 2.3;                 ///< [Hz]
  double roll_amplitude = 1.5 * M_PI / 180.0;   ///< [rad]
  double roll_frequency = 1.7;                  ///< [Hz]
};

/// A planar trajectory (x, y, yaw) on rough ground: z, roll and pitch oscillate (RoughGround), so tf
/// is fully 3D. pose(t) = fromXyzRpy(x(t), y(t), z(t), roll(t), pitch(t), yaw(t)).
class RoughGroundTrajectory3 final : public Trajectory3 {
 public:
  RoughGroundTrajectory3(std::shared_ptr<const Trajectory> planar, const RoughGround& ground = {})
      : planar_(std::move(planar)), ground_(ground) {}
  Pose3 pose(double t) const override;
  const RoughGround& ground() const { return ground_; }

 private:
  std::shared_ptr<const Trajectory> planar_;
  RoughGround ground_;
};

/// A spinning multi-line LIDAR. One revolution per sweep; `columns` firings per revolution, evenly
/// spaced in azimuth and in time; all rings of a column fire together from the sensor origin (the real
/// sensors fire a column's lasers within a few us, and their beams leave a few cm off the axis: both
/// left out). Column c of a sweep starting at t0 fires at t0 + c / (rate columns), at azimuth
/// pi + c 2pi/columns (counter-clockwise seen from above) or pi - c 2pi/columns (clockwise): every
/// sweep starts and ends facing backwards (-x), where the drivers cut it.
/// Ring r looks up by ring_elevations[r]; the direction of (ring, azimuth a) in the sensor frame is
/// (cos e cos a, cos e sin a, sin e).
struct SpinningLidarModel {
  std::string name;
  std::vector<double> ring_elevations;  ///< [rad] per ring, in the driver's ring order
  int columns = 1024;                   ///< firings per revolution
  double rate = 10.0;                   ///< [Hz] revolutions (sweeps) per second
  bool clockwise = false;               ///< seen from above (+z)
  bool organized = false;               ///< keep no-return points as zeros (rings x columns image)
  double range_sigma = 0.0;             ///< [m] Gaussian range noise (used when noise is on)
  double range_min = 0.3;               ///< [m] closer hits are no return
  double range_max = 100.0;             ///< [m] farther hits are no return

  int rings() const { return static_cast<int>(ring_elevations.size()); }
  double sweepPeriod() const { return 1.0 / rate; }                                    ///< [s]
  double columnPeriod() const { return 1.0 / (rate * static_cast<double>(columns)); }  ///< [s]
  /// Azimuth [rad] of column c in the sensor frame (not wrapped).
  double azimuth(int column) const;
  /// Unit beam direction of (ring, column) in the sensor frame.
  Eigen::Vector3d direction(int ring, int column) const;

  /// Velodyne VLP-16: 16 rings -15..+15 deg in 2 deg steps (ring 0 lowest), 1800 columns (0.2 deg),
  /// 10 Hz, clockwise (as Velodynes spin), dense, sigma 3 cm, range 0.5-100 m.
  static SpinningLidarModel vlp16();
  /// Ouster OS1-64: 64 rings evenly over +16.6..-16.6 deg (ring 0 highest, as Ouster's row 0), 1024
  /// columns, 10 Hz, organized 64 x 1024 with zeros for no return, sigma 3 cm, range 0.3-120 m.
  /// It spins counter-clockwise here. (A real Ouster turns clockwise seen from above: its encoder
  /// azimuth counts clockwise in its own frame. We keep counter-clockwise so that the two factories
  /// cover both spin directions; nothing in a driver's cloud layout depends on it.)
  static SpinningLidarModel os1_64();
  /// The model of that name ("VLP16" or "OS1-64"); throws std::invalid_argument otherwise.
  static SpinningLidarModel byName(const std::string& name);
};

/// One simulated point and its truth.
struct SimulatedPoint {
  Eigen::Vector3d position;   ///< [m] measured, in the sensor frame at its own firing time; 0 if none
  double range = 0.0;         ///< [m] measured (with noise if on); 0 if no return
  double time = 0.0;          ///< [s] firing time on the simulation clock (t = 0 at the epoch)
  int ring = 0;               ///< index into ring_elevations
  int column = 0;             ///< firing index in the sweep, 0 .. columns-1
  Eigen::Vector3d world_hit;  ///< [m] true hit in the world (NaN if no return)
  bool is_return = false;     ///< a hit within [range_min, range_max]
};

/// One sweep (one revolution) and its truth.
/// Order: dense models keep only returns, in firing order (column by column, rings 0.. within a
/// column), as Velodyne-style drivers emit them. Organized models keep every (ring, column), no-return
/// points as zeros, as an image with row = ring and column = column, row-major:
/// points[ring * columns + column] (ouster-ros' layout: height = rings, width = columns).
struct SimulatedCloud {
  std::vector<SimulatedPoint> points;
  double start_time = 0.0;  ///< [s] column 0's firing time
  double end_time = 0.0;    ///< [s] the last column's firing time
  int rings = 0;
  int columns = 0;
  bool organized = false;
};

/// Casts every ray from the sensor's TRUE pose at its column's time: sensor = base(t) (+) mount.
/// `start_time` [s] is column 0's time. `noise`: Gaussian range noise of model.range_sigma along the
/// beam when given; exact ranges when null (world_hit stays the true hit either way).
SimulatedCloud simulateSweep(const World3& world, const Trajectory3& trajectory, const Pose3& mount,
                             const SpinningLidarModel& model, double start_time,
                             std::mt19937* noise = nullptr);

/// Distance [m] from each point, given in the sensor frame at `sensor_pose`, to the nearest true
/// surface: how a corrected cloud is scored (placed with the sensor's true pose at the reference time).
std::vector<double> distancesToWorld(const World3& world, const Pose3& sensor_pose,
                                     const std::vector<Eigen::Vector3d>& points);

}  // namespace lidar_deskew::sim
