// Latency of the live deskew, in real time: plays the simulator's arc through /tf at 50 Hz and its scans
// as a driver publishes them (when their last beam is measured), for a while, then prints the node's
// own diagnostics: latency from "tf covers the last beam" to publish (p99), tf wait, processing, drops.
// Run by bench/latency.sh, which starts roscore and the node.
//
//   latency_driver [--seconds S] [--sensor UTM-30LX|ILD26TRI]
#include <cstdio>
#include <cstring>
#include <string>

#include "../test/ros/live_rig.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "latency_driver");
  double seconds = 30.0;
  std::string sensor = "UTM-30LX";
  for (int a = 1; a + 1 < argc; a += 2) {
    if (!std::strcmp(argv[a], "--seconds"))
      seconds = std::atof(argv[a + 1]);
    if (!std::strcmp(argv[a], "--sensor"))
      sensor = argv[a + 1];
  }
  using namespace lidar_deskew;
  const sim::LidarModel model =
      sensor == "ILD26TRI" ? sim::LidarModel::ild26tri() : sim::LidarModel::utm30lx360();
  test::LiveRig rig(model);
  if (!rig.connect()) {
    std::fprintf(stderr, "latency_driver: the deskew did not subscribe to scan\n");
    return 1;
  }
  const double period = 1.0 / model.rate;
  int published = 0;
  const ros::WallTime start = ros::WallTime::now();
  double next_scan = 0.0;  // start time of the next scan [s]
  for (;;) {
    const double now = (ros::WallTime::now() - start).toSec();
    if (now > seconds)
      break;
    rig.publishTfUntil(now);             // odometry as it happens
    while (next_scan + period <= now) {  // a scan is published once its sweep is over
      rig.publishScan(next_scan);
      ++published;
      next_scan += period;
    }
    ros::spinOnce();
    ros::WallDuration(0.001).sleep();
  }
  rig.publishTfUntil((ros::WallTime::now() - start).toSec() + 0.05);
  // Diagnostics come once per second: wait for one that has seen every scan.
  rig.waitFor([&] { return rig.diagnosticNumber("received") >= published; }, 5.0);
  rig.waitFor([&] { return false; }, 1.5);
  std::printf("%s, %d scans in %.0f s of real time (tf 50 Hz)\n", model.name.c_str(), published, seconds);
  for (const char* key :
       {"received", "published", "dropped: tf", "dropped: queue", "dropped: invalid", "tf wait mean [ms]",
        "tf wait max [ms]", "processing mean [us]", "processing max [us]", "latency p99 [ms]"}) {
    std::printf("  %-22s %s\n", key, rig.diagnostic(key).c_str());
  }
  return 0;
}
