// Latency of the live deskew, in real time: plays the simulator's arc through /tf at 50 Hz and the scans
// of one or more sensors as a driver publishes them (when their last beam is measured), for a while,
// then prints each deskew's own diagnostics: latency from "tf covers the last beam" to publish (p99),
// tf wait, processing, drops. Run by bench/latency.sh and bench/soak.sh, which start roscore and the
// deskew.
//
//   latency_driver [--seconds S] [--sensor UTM-30LX|ILD26TRI[:NAMESPACE]]...
//
// Each sensor publishes `scan` in its namespace (none by default) and reads the diagnostics of the
// deskew named in it; the first sensor's rig publishes the tf that serves all of them.
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "../test/node/live_rig.h"

namespace {

struct Stream {
  std::unique_ptr<lidar_deskew::test::LiveRig> rig;
  std::string label;
  double period = 0.0;
  double next_scan = 0.0;  // start time of the next scan [s]
  int published = 0;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "latency_driver");
  using namespace lidar_deskew;
  double seconds = 30.0;
  std::vector<std::string> sensors;
  for (int a = 1; a + 1 < argc; a += 2) {
    if (!std::strcmp(argv[a], "--seconds"))
      seconds = std::atof(argv[a + 1]);
    if (!std::strcmp(argv[a], "--sensor"))
      sensors.push_back(argv[a + 1]);
  }
  if (sensors.empty())
    sensors.push_back("UTM-30LX");
  std::vector<Stream> streams;
  for (const std::string& sensor : sensors) {
    const std::size_t colon = sensor.find(':');
    const std::string name = sensor.substr(0, colon);
    const std::string ns = colon == std::string::npos ? "" : sensor.substr(colon + 1);
    const sim::LidarModel model =
        name == "ILD26TRI" ? sim::LidarModel::ild26tri() : sim::LidarModel::utm30lx360();
    Stream stream;
    stream.rig = std::make_unique<test::LiveRig>(model, ns);
    stream.rig->limitHistory(50);
    if (!streams.empty())
      stream.rig->shareClockWith(*streams.front().rig);
    stream.label = model.name + (ns.empty() ? "" : " in /" + ns);
    stream.period = 1.0 / model.rate;
    if (!stream.rig->connect()) {
      std::fprintf(stderr, "latency_driver: no deskew subscribed to %s/scan\n", ns.c_str());
      return 1;
    }
    streams.push_back(std::move(stream));
  }
  test::LiveRig& clock = *streams.front().rig;
  const ros::WallTime start = ros::WallTime::now();
  const double offset = clock.secondsOf(ros::Time::now());  // the rigs' t of `start`
  for (;;) {
    const double now = (ros::WallTime::now() - start).toSec();
    if (now > seconds)
      break;
    clock.publishTfUntil(offset + now);  // odometry as it happens
    for (Stream& stream : streams) {
      while (stream.next_scan + stream.period <= now) {  // a scan is published once its sweep is over
        stream.rig->publishScan(offset + stream.next_scan);
        ++stream.published;
        stream.next_scan += stream.period;
      }
    }
    ros::spinOnce();
    ros::WallDuration(0.001).sleep();
  }
  clock.publishTfUntil(offset + (ros::WallTime::now() - start).toSec() + 0.05);
  // Diagnostics come once per second: wait for one that has seen every scan.
  for (Stream& stream : streams)
    stream.rig->waitFor([&] { return stream.rig->diagnosticNumber("received") >= stream.published; }, 5.0);
  clock.spinFor(1.5);
  for (const Stream& stream : streams) {
    std::printf("%s, %d scans in %.0f s of real time (tf 50 Hz)\n", stream.label.c_str(), stream.published,
                seconds);
    std::printf("  %-22s %.0f\n", "lost before the deskew",
                stream.published - stream.rig->diagnosticNumber("received"));
    for (const char* key :
         {"received", "published", "dropped: tf", "dropped: queue", "dropped: invalid", "dropped: mount",
          "tf gaps", "time jumps", "tf wait mean [ms]", "tf wait max [ms]", "processing mean [us]",
          "processing max [us]", "latency p99 [ms]"}) {
      std::printf("  %-22s %s\n", key, stream.rig->diagnostic(key).c_str());
    }
  }
  return 0;
}
