// The timing conventions of the common 2D LIDAR drivers, as their public sources write a LaserScan, for
// the planar simulator (deskew_simulate --driver; docs/REAL_ROBOTS.md). ROS-free.
//
// Each driver is simulated with one typical sensor (its beams, rate, field of view, range) and its
// convention as a TimingFault: what header.stamp is, the beams' time order against their index order,
// and what time_increment and scan_time say. Read from (repository, branch or tag, file):
//
// - kRplidar: Slamtec/rplidar_ros master 3cd94fe and ros2 1597018, src/node.cpp publish_scan (l. 56-110)
//   and the loop (l. 390-466); Slamtec/sllidar_ros2 main 3430009, src/sllidar_node.cpp (l. 201-250,
//   355-428). RPLIDAR A1: 720 beams (angle_compensate: 360 x 2), 360 deg, 7.6 Hz, 0.15-12 m. The sensor
//   turns clockwise; the ranges are written against the spin (ranges[n-1-i] = node i): the earliest
//   beam is index n-1. header.stamp = ros::Time::now() taken just before grabScanDataHq() waits for the
//   next complete revolution, which the steady loop enters as that revolution begins: the earliest
//   beam's time (plus the serial link's few ms, not simulated). scan_time = the wait (one period),
//   time_increment = scan_time / (n - 1): n/(n-1) x the true beam period.
// - kUrgNode: ros-drivers/urg_node melodic-devel 08b675c, src/urg_c_wrapper.cpp (grabScan l. 206-246;
//   getScanPeriod, getTimeIncrement l. 723-740; getAngularTimeOffset l. 907; ros2-devel 369ee4d the
//   same, l. 215-234, 868-878); urg_c master
//   bbe007f current/src/urg_sensor.c l. 642-651. Hokuyo UTM-30LX: 1080 beams, 270 deg, 40 Hz,
//   counter-clockwise, index order. header.stamp = the host's time when the scan's data arrive (after
//   its last beam) + the time from the sensor's rear to angle_min, (angle_min + pi) / 2pi x period
//   (calibrate_time: false, the default). time_increment and scan_time are the sensor's, right.
// - kSickScan: SICKAG/sick_scan master b44cd27, driver/src/sick_scan_common.cpp (stamp l. 3004,
//   3083-3110; scan_time, time_increment l. 3165-3172; angles l. 3414-3421; beam times l. 3448). SICK
//   TiM571: 810 beams, 270 deg (1/3 deg), 15 Hz, index order. header.stamp = the telegram's
//   SystemCountScan (the scan's first measurement) on the host clock through the driver's software PLL,
//   + the time_offset parameter (0 by default): the first beam. time_increment = 1 / the telegram's
//   measurement frequency, scan_time = 1 / its scan frequency: right.
// - kHlsLfcdLds: ROBOTIS-GIT/hls_lfcd_lds_driver noetic-devel 4485748 and main 5bf13c1,
//   src/hlds_laser_publisher.cpp (poll l. 57-135, stamp l. 171). TurtleBot3 LDS-01: 360 beams, 360 deg,
//   5 Hz, 0.12-3.5 m, clockwise spin written as ranges[359 - index]: the earliest beam is index 359.
//   header.stamp = ros::Time::now() after the whole revolution's 2520 bytes were read: the latest beam
//   (index 0). time_increment = 1 / (6 rpm), scan_time = 360 x that: right (since 2020-09-08, commit
//   4275fef; before it time_increment = speed / 1e8, 0.054 x the truth).
// - kLdlidar: ldrobotSensorTeam/ldlidar_stl_ros v3.0.3 964afad, src/publish_node/main.cpp
//   ToLaserscanMessagePublish (l. 127-224). LD06 / LD19: 450 beams (4500 Hz / 10 Hz), 360 deg, 10 Hz,
//   0.02-12 m; the sensor turns clockwise and laser_scan_dir: true (the default) writes
//   ranges[n - 1 - index]: the earliest beam is index n-1. header.stamp = ros::Time::now() when the
//   revolution is complete: the latest beam. scan_time = the time since the last publish (one period),
//   time_increment = scan_time / (n - 1).
// - kYdlidar: YDLIDAR/ydlidar_ros_driver master 2bf0e2a, src/ydlidar_ros_driver.cpp (l. 194-233), and
//   YDLIDAR/YDLidar-SDK master 01cdda4, src/CYdLidar.cpp (l. 597-620, 713-722). YDLIDAR X4: 500 beams,
//   360 deg, 10 Hz, 0.12-10 m; clockwise, inverted: true (the default) writes angle 2pi - a, so the
//   earliest beam is the last index. header.stamp = the first point's time (its packet's arrival).
//   scan_time = the time between the revolutions' last points, time_increment = scan_time / n: right.
// - kXv11: rohbotics/xv_11_laser_driver kinetic-devel 0.3.0 0d388b1, src/neato_laser_publisher.cpp
//   (l. 66-72) and src/xv11_laser.cpp (firmware 2, l. 104-165). Neato XV-11: 360 beams, 360 deg, 5 Hz
//   (300 rpm), index order. header.stamp = ros::Time::now() before poll() waits for the revolution's
//   first packet: its first beam. time_increment = the packets' mean speed field (64 x rpm) / 1e8 =
//   64 rpm / 1e8 s, 0.3456 x the true 1 / (6 rpm) at 300 rpm; scan_time never set: 0.
// - kLd08: ROBOTIS-GIT/ld08_driver main c54a8f3 (TurtleBot3 LDS-02), src/lipkg.cpp (frame at the
//   angle's wrap, sorted by angle, l. 177-196; ToLaserscan l. 219-262) and src/main.cpp (l. 78-86).
//   LDS-02: 460 beams (2300 Hz / 5 Hz), 360 deg, 5 Hz, 0.16-8 m, index order (the device's angle as it
//   comes). header.stamp = now() when the 100 Hz loop finds the frame ready: the latest beam (0-10 ms
//   later, not simulated). scan_time = 360 / speed, time_increment = scan_time / ((angle_max -
//   angle_min) / angle_increment) = scan_time / (n - 1).
//
// Not simulated (geometry, not timing): RPLIDAR's and ldlidar's angle_increment = 2pi / (n - 1) over n
// beams of one revolution; the link's latency (serial, USB, Ethernet), which deskew_calibrate measures.
#pragma once

#include <string>
#include <vector>

#include "lidar_deskew/sim/scenario.h"

namespace lidar_deskew::sim {

enum class LaserDriver { kRplidar, kUrgNode, kSickScan, kHlsLfcdLds, kLdlidar, kYdlidar, kXv11, kLd08 };

/// Every driver, in the enum's order.
const std::vector<LaserDriver>& allLaserDrivers();
/// "rplidar", "urg_node", "sick_scan", "hls_lfcd_lds", "ldlidar", "ydlidar", "xv_11", "ld08".
std::string laserDriverName(LaserDriver driver);
std::vector<std::string> laserDriverNames();
/// The driver of that name; throws std::invalid_argument listing the names otherwise.
LaserDriver laserDriverFromName(const std::string& name);

/// The sensor the driver is simulated with (see above): its name is the sensor's, e.g. "RPLIDAR-A1".
LidarModel driverLidar(LaserDriver driver);
/// The driver's timing convention for `lidar` (normally driverLidar(driver)) as the fault its messages
/// carry against the simulator's truth (stamp_error = stamp - earliest beam [s], reversed,
/// time_increment_factor, zero_scan_time). Throws std::invalid_argument naming the driver for a lidar
/// whose rate is not finite and positive or that has fewer than 2 beams.
TimingFault driverTiming(LaserDriver driver, const LidarModel& lidar);
/// The driver's sensor on the timing-calibration drive (the "turns" drive of calibrationScenarios() at
/// `speed`, "normal" or "high"), named "<sensor>/<speed>/turns/<driver>".
Scenario driverScenario(LaserDriver driver, const std::string& speed = "normal");

}  // namespace lidar_deskew::sim
