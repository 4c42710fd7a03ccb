// The paper's simulation experiments as named scenarios, and the ground-truth file that goes with a
// simulated bag. ROS-free.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lidar_deskew/sim/sim.h"

namespace lidar_deskew::sim {

/// One experiment: a LIDAR on a robot moving through a world (the hall, unless said otherwise).
struct Scenario {
  std::string name;  ///< e.g. "UTM-30LX/high/arc"
  LidarModel lidar;
  /// "normal" (1.5 m/s, 2 rad/s; turns: 1 m/s, 2 rad/s), "high" (6 m/s, 5 rad/s; turns: 2 m/s,
  /// 5 rad/s) or "varying"
  std::string speed;
  std::string motion;  ///< "translation", "rotation", "arc", "varying", "turns", "spin", "circle", "smooth"
  Pose2 mount;         ///< laser on the base
  Pose2 start;         ///< base pose in the world at t = 0
  std::vector<MotionPiece> pieces;
  double duration = 1.0;        ///< [s] scans start at 0, 1/rate, ... while below duration
  World world = World::hall();  ///< where the robot drives

  PiecewiseTrajectory trajectory() const { return PiecewiseTrajectory(start, pieces); }
};

/// The paper's table: UTM-30LX 1440/360 deg/40 Hz, ILD26TRI 360/360 deg/8 Hz, UTM-30LX 1080/270 deg/
/// 40 Hz; translation, rotation and both; normal speed (1.5 m/s, 2 rad/s, laser on the rotation centre)
/// and high speed (6 m/s, 5 rad/s, laser 0.25 m ahead, 0.05 m left, turned 0.1 rad). Plus "varying":
/// the ILD26TRI with speed and turn rate changing inside each scan. 19 scenarios. Then the LDS-01
/// (360 beams, 5 Hz, 3.5 m) for 8 scans (1.6 s) in World::smallRoom(), laser 32 mm behind the base:
/// "LDS-01/normal/translation" (from (-1.5, -0.4) heading +x), "LDS-01/normal/rotation" and
/// "LDS-01/high/rotation" (in the middle), "LDS-01/normal/arc" and "LDS-01/high/arc" (circles about
/// the middle, radius v / w = 0.75 m and 1.2 m) at the paper's speeds; no high-speed translation
/// (9.6 m in 8 scans does not fit the room). 24 scenarios.
std::vector<Scenario> paperScenarios();
/// Recordings for estimating a sensor's timing (deskew_calibrate): motion "turns", a drive of about
/// 14 s whose turn rate changes every 1 to 2 s (standing still, turning in place both ways, straight,
/// arcs), so scans taken at different turn rates see the same walls. "normal": up to 1 m/s and
/// 2 rad/s; "high": up to 2 m/s and 5 rad/s. For ILD26TRI, UTM-30LX, UTM-30LX-270 (in the hall,
/// mount as in the paper's speeds) and LDS-01 (in World::smallRoom(), its 3.5 m reach; laser 32 mm
/// behind the base as on a TurtleBot3 Burger). "<sensor>/normal/turns", "<sensor>/high/turns":
/// 8 scenarios, not part of paperScenarios() (docs/RESULTS.md). Then 6 steady drives, one constant
/// twist for 12 s, in which an offset cannot show: "<sensor>/normal/spin" (1.5 rad/s in place) and
/// "<sensor>/normal/circle" (0.5 m/s, 1 rad/s) for ILD26TRI, UTM-30LX and LDS-01.
std::vector<Scenario> calibrationScenarios();
/// The "turns" drive of calibrationScenarios() (speed "normal" or "high") with any `lidar`: in
/// World::smallRoom() with the laser 32 mm behind the base when its range_max is below 10 m, else in the
/// hall. Named "<lidar.name>/<speed>/turns".
Scenario turnsScenario(const LidarModel& lidar, const std::string& speed);
/// Motion whose twist changes all the time, between odometry samples too (sim::smoothUnicyclePieces):
/// the speed follows a cosine of period 2 s from its peak through zero into reverse, the turn rate one
/// of period 1.3 s; "normal" peaks at 1.5 m/s and 2 rad/s, "high" at 6 m/s and 5 rad/s. Laser 0.25 m
/// ahead, 0.05 m left, turned 0.1 rad; 1.3 s of scans. UTM-30LX, ILD26TRI and UTM-30LX-270 in the hall
/// (start (-10, -1.5)), LDS-01 in World::smallRoom(). "<sensor>/normal/smooth", "<sensor>/high/smooth":
/// 8 scenarios (docs/RESULTS.md).
std::vector<Scenario> smoothScenarios();
/// Every planar scenario: paperScenarios(), calibrationScenarios(), then smoothScenarios().
std::vector<Scenario> planarScenarios();
/// The planar scenario of that name; throws std::invalid_argument listing the names otherwise.
Scenario findScenario(const std::string& name);
/// The same experiment with the sensor turning clockwise (negative angle increment); name + "/clockwise".
Scenario clockwiseVariant(Scenario scenario);

/// The laser's mount changed (re-published on /tf_static, as after a recalibration): the sweeps that end
/// at or after `time` [s since t = 0] were taken with `mount`.
struct MountChange {
  double time = 0.0;
  Pose2 mount;
};

/// How a robot's odometry samples come (sim_bag's /tf odom -> base_link and /odom), beyond its noise:
/// the defaults are the ideal 50 Hz grid, stamped at the true time and recorded at once.
struct OdometryTiming {
  /// [s] each stamp = the sample's true time + u, u uniform in [-jitter, +jitter] (a driver that stamps
  /// on receipt); the pose stays the one at the true time.
  double jitter = 0.0;
  /// [Hz] irregular rate: each next sample a uniform random interval in [1 / rate_max, 1 / rate_min]
  /// after the last; 0 = the regular tf_rate grid.
  double rate_min = 0.0;
  double rate_max = 0.0;
  /// [m] wheel travel per encoder tick (0: not quantised) and [m] the wheel base of the differential
  /// drive: each wheel's travel (s -/+ wheel_base / 2 * dyaw along the odometry's motion, from a random
  /// encoder phase) counted in whole ticks, the pose integrated from the tick counts of each interval
  /// (ds = tick (nl + nr) / 2, dyaw = tick (nr - nl) / wheel_base, exact along an arc).
  double tick = 0.0;
  double wheel_base = 0.0;
  /// [s] each sample recorded this long after its stamp.
  double late = 0.0;
  /// Samples recorded in bursts of this many, all at the record time of the burst's last (1: none).
  int burst = 1;

  bool any() const { return jitter != 0.0 || rate_min != 0.0 || tick != 0.0 || late != 0.0 || burst != 1; }
  /// Throws std::invalid_argument naming the field: a negative or non-finite value, rate_min > rate_max
  /// or only one of them 0, tick without a positive wheel_base, burst < 1.
  void validate() const;
};

/// One odometry sample as a robot's driver publishes it.
struct OdometrySample {
  double time = 0.0;    ///< [s] the true time its pose is of
  double stamp = 0.0;   ///< [s] as the message says: time + the jitter
  double record = 0.0;  ///< [s] when recorded: stamp + late, or its burst's last sample's
  Pose2 pose;           ///< what the odometry reports (x, y, yaw)
  /// The twist it reports: the true one x the step's factors (NoisyOdometry), or with encoder ticks the
  /// interval's ticks over its duration.
  double speed = 0.0;     ///< [m/s]
  double yaw_rate = 0.0;  ///< [rad/s]
};

/// What a wheeled robot's odometry records of the planar motion `truth` (both bag writers' /tf):
/// - times: the grid begin + k / rate [s], k = 0 .. last (the caller's rounding of its span; with
///   timing.jitter, ceil(jitter rate) more at each end), or with timing.rate_min > 0 random intervals
///   from begin - jitter until end + jitter is passed (OdometryTiming);
/// - poses: NoisyOdometry(truth, first time, max(end, last time), noise, seed, yaw_scale) at the true
///   times; with timing.tick integrated from whole encoder ticks along it (OdometryTiming::tick);
/// - stamps jittered, record times late and in bursts (OdometryTiming).
/// Timing draws come from a generator seeded with (seed, 0x0d0e7), apart from the noise's. Returned in
/// the order a recorder writes them: by record time, ties in time order. Throws std::invalid_argument
/// for an invalid timing, noise or yaw_scale.
std::vector<OdometrySample> recordOdometry(const PiecewiseTrajectory& truth, double begin, long last,
                                           double end, double rate, double noise, unsigned seed,
                                           double yaw_scale, const OdometryTiming& timing);

/// What the metrics need to know about a simulated bag: the world, the true motion, the mount, and
/// how the scans' timing was faulted.
struct Truth {
  std::string scenario;
  core::TimeNs epoch = 0;    ///< [ns] bag time of t = 0
  double range_sigma = 0.0;  ///< [m] range noise used (0 = off)
  Pose2 mount;
  /// The mount from a time on (none in files written before it existed).
  std::optional<MountChange> mount_change;
  Pose2 start;
  std::vector<MotionPiece> pieces;
  World world;
  /// The messages' timing fault (none in files written before faults existed).
  TimingFault timing_fault;
  /// [s] true time between consecutive beams (0: not recorded, an older file).
  double beam_period = 0.0;
  /// [s] true time between scans, 1 / rate (0: not recorded, an older file).
  double sweep_period = 0.0;
  /// The bag's odometry error (sim::NoisyOdometry's relative_noise; 0 = perfect odometry, as in files
  /// written before it existed) and the seed of its generator. The motion above stays the true one.
  double odom_noise = 0.0;
  unsigned odom_noise_seed = 0;
  /// The odometry's yaw increments x this (sim::NoisyOdometry's yaw_scale; 1 in files without it).
  double odom_yaw_scale = 1.0;
  /// The odometry samples' timing, quantisation and delivery (none in files without it).
  OdometryTiming odom_timing;

  PiecewiseTrajectory trajectory() const { return PiecewiseTrajectory(start, pieces); }
  /// The mount in force at bag time `time` [ns] (mount_change's from its time on).
  Pose2 mountAt(core::TimeNs time) const;
  /// True laser pose in the world at bag time `time` [ns], with mountAt(time) (the sweep's own mount
  /// unless a sweep spans the change, which the simulator's bags avoid: see SimBagOptions).
  Pose2 laserPose(core::TimeNs time) const;
  /// [s] the parameter that corrects the stamps: true earliest-beam time = stamp + timeOffset().
  double timeOffset() const { return 0.0 - timing_fault.stamp_error; }
  /// [ns] true time of beam `index` of a scan of `beams` beams stamped `stamp` (needs beam_period).
  core::TimeNs beamTime(core::TimeNs stamp, std::size_t index, std::size_t beams) const;
};

/// Writes / reads the ground-truth file (a small line-based text format, full double precision).
/// The timing lines: "time_offset S" (= -stamp_error), "reversed 0|1", "time_increment_factor F",
/// "zero_scan_time 0|1", "beam_period S", "sweep_period S"; absent in older files, which read as no
/// fault and periods 0. The odometry lines "odom_noise R", "odom_noise_seed N"; absent: 0 (perfect);
/// "odom_yaw_scale F" only when not 1; "odom_jitter S", "odom_rate LO HI", "odom_ticks M B",
/// "odom_late S", "odom_burst N" only when set.
/// "mount_change T X Y YAW" only when the mount changed.
/// read throws std::runtime_error naming the file and line on malformed input.
void writeTruth(const Truth& truth, const std::string& path);
Truth readTruth(const std::string& path);

}  // namespace lidar_deskew::sim
