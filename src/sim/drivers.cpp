#include "lidar_deskew/sim/drivers.h"

#include <cmath>
#include <stdexcept>

namespace lidar_deskew::sim {

const std::vector<LaserDriver>& allLaserDrivers() {
  static const std::vector<LaserDriver> drivers = {
      LaserDriver::kRplidar, LaserDriver::kUrgNode, LaserDriver::kSickScan, LaserDriver::kHlsLfcdLds,
      LaserDriver::kLdlidar, LaserDriver::kYdlidar, LaserDriver::kXv11,     LaserDriver::kLd08};
  return drivers;
}

std::string laserDriverName(LaserDriver driver) {
  switch (driver) {
    case LaserDriver::kRplidar:
      return "rplidar";
    case LaserDriver::kUrgNode:
      return "urg_node";
    case LaserDriver::kSickScan:
      return "sick_scan";
    case LaserDriver::kHlsLfcdLds:
      return "hls_lfcd_lds";
    case LaserDriver::kLdlidar:
      return "ldlidar";
    case LaserDriver::kYdlidar:
      return "ydlidar";
    case LaserDriver::kXv11:
      return "xv_11";
    case LaserDriver::kLd08:
      return "ld08";
  }
  throw std::invalid_argument("unknown LaserDriver");
}

std::vector<std::string> laserDriverNames() {
  std::vector<std::string> names;
  for (const LaserDriver driver : allLaserDrivers())
    names.push_back(laserDriverName(driver));
  return names;
}

LaserDriver laserDriverFromName(const std::string& name) {
  std::string known;
  for (const LaserDriver driver : allLaserDrivers()) {
    if (laserDriverName(driver) == name)
      return driver;
    known += " " + laserDriverName(driver);
  }
  throw std::invalid_argument("unknown driver '" + name + "'; known:" + known);
}

LidarModel driverLidar(LaserDriver driver) {
  // {name, beams, field of view [rad], rate [Hz], range sigma [m], clockwise, range_min, range_max [m]}:
  // the data sheets' figures; sigma about their accuracy at a few metres.
  switch (driver) {
    case LaserDriver::kRplidar:
      return {"RPLIDAR-A1", 720, 2.0 * M_PI, 7.6, 0.02, false, 0.15f, 12.0f};
    case LaserDriver::kUrgNode:
      return LidarModel::utm30lx270();
    case LaserDriver::kSickScan:
      return {"TiM571", 810, 1.5 * M_PI, 15.0, 0.02, false, 0.05f, 25.0f};
    case LaserDriver::kHlsLfcdLds:
      return LidarModel::lds01();
    case LaserDriver::kLdlidar:
      return {"LD06", 450, 2.0 * M_PI, 10.0, 0.02, false, 0.02f, 12.0f};
    case LaserDriver::kYdlidar:
      return {"YDLIDAR-X4", 500, 2.0 * M_PI, 10.0, 0.02, false, 0.12f, 10.0f};
    case LaserDriver::kXv11:
      return {"XV-11", 360, 2.0 * M_PI, 5.0, 0.02, false, 0.06f, 5.0f};
    case LaserDriver::kLd08:
      return {"LDS-02", 460, 2.0 * M_PI, 5.0, 0.02, false, 0.16f, 8.0f};
  }
  throw std::invalid_argument("unknown LaserDriver");
}

TimingFault driverTiming(LaserDriver driver, const LidarModel& lidar) {
  if (!(lidar.rate > 0.0) || !std::isfinite(lidar.rate) || lidar.beams < 2)
    throw std::invalid_argument(laserDriverName(driver) +
                                ": the lidar needs a finite rate > 0 and 2 beams or more");
  TimingFault timing;
  const double beams = lidar.beams;
  const double true_increment = static_cast<double>(lidar.timeIncrement());
  switch (driver) {
    case LaserDriver::kRplidar:  // against the spin, stamped at the earliest beam, scan_time / (n - 1)
      timing.reversed = true;
      timing.time_increment_factor = beams / (beams - 1.0);
      break;
    case LaserDriver::kUrgNode:  // the data's arrival after the last beam + (angle_min + pi) / 2pi periods
      timing.stamp_error =
          lidar.sweepDuration() + (static_cast<double>(lidar.angleMin()) + M_PI) / (2.0 * M_PI) / lidar.rate;
      break;
    case LaserDriver::kSickScan:  // the sensor's own time of the first beam: right
      break;
    case LaserDriver::kHlsLfcdLds: {  // against the spin, stamped at the latest beam, 1 / (6 rpm)
      timing.reversed = true;
      timing.stamp_error = lidar.sweepDuration();
      const double rpm = std::floor(60.0 * lidar.rate);  // integer division in the driver
      timing.time_increment_factor = 1.0 / (6.0 * rpm) / true_increment;
      break;
    }
    case LaserDriver::kLdlidar:  // against the spin, stamped at the latest beam, scan_time / (n - 1)
      timing.reversed = true;
      timing.stamp_error = lidar.sweepDuration();
      timing.time_increment_factor = beams / (beams - 1.0);
      break;
    case LaserDriver::kYdlidar:  // against the spin, stamped at the earliest beam, scan_time / n
      timing.reversed = true;
      break;
    case LaserDriver::kXv11: {  // stamped at the first beam, time_increment 64 rpm / 1e8, no scan_time
      const double rpm = 60.0 * lidar.rate;
      timing.time_increment_factor = 64.0 * rpm / 1e8 / true_increment;
      timing.zero_scan_time = true;
      break;
    }
    case LaserDriver::kLd08:  // stamped at the latest beam, scan_time / (n - 1)
      timing.stamp_error = lidar.sweepDuration();
      timing.time_increment_factor = beams / (beams - 1.0);
      break;
  }
  return timing;
}

Scenario driverScenario(LaserDriver driver, const std::string& speed) {
  Scenario scenario = turnsScenario(driverLidar(driver), speed);
  scenario.name += "/" + laserDriverName(driver);
  return scenario;
}

}  // namespace lidar_deskew::sim
