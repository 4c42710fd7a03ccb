// libFuzzer target for the ROS-free core: any scan geometry, ranges, time fields, configs and pose
// samples go through validation, timing, correction and re-binning. Findings: a crash, a sanitizer
// report, or a broken invariant (a NaN point, a re-binned scan of the wrong size).
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdlib>

#include "lidar_deskew/core/deskew.h"
#include "lidar_deskew/core/rebin.h"

namespace {

using namespace lidar_deskew::core;

/// A float from raw bits half of the time (NaN, inf, denormals...), else a plausible value.
float anyFloat(FuzzedDataProvider& data, float low, float high) {
  if (data.ConsumeBool())
    return data.ConsumeFloatingPoint<float>();
  return data.ConsumeFloatingPointInRange<float>(low, high);
}

void check(bool condition) {
  if (!condition)
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* bytes, size_t size) {
  FuzzedDataProvider data(bytes, size);
  PlanarScan scan;
  scan.stamp = data.ConsumeIntegralInRange<TimeNs>(-(TimeNs{1} << 62), TimeNs{1} << 62);
  scan.angle_min = anyFloat(data, -7.0f, 7.0f);
  scan.angle_increment = anyFloat(data, -0.1f, 0.1f);
  scan.time_increment = anyFloat(data, -1e-3f, 1e-3f);
  scan.scan_time = anyFloat(data, 0.0f, 1.0f);
  scan.range_min = anyFloat(data, 0.0f, 1.0f);
  scan.range_max = anyFloat(data, 0.0f, 100.0f);
  const std::size_t beams = data.ConsumeIntegralInRange<std::size_t>(0, 1500);
  for (std::size_t i = 0; i < beams && data.remaining_bytes() > 0; ++i)
    scan.ranges.push_back(anyFloat(data, 0.0f, 40.0f));
  if (data.ConsumeBool())
    scan.intensities.resize(data.ConsumeBool() ? scan.ranges.size()
                                               : data.ConsumeIntegralInRange<std::size_t>(0, 5));

  TimingConfig timing;
  timing.stamp_at = data.ConsumeBool() ? StampAt::kStart : StampAt::kEnd;
  timing.scan_period = data.ConsumeBool() ? 0.0 : data.ConsumeFloatingPointInRange<double>(0.0, 0.5);
  DeskewConfig config;
  config.reference = static_cast<Reference>(data.ConsumeIntegralInRange<int>(0, 2));
  config.knot_interval = data.PickValueInArray({0.0, 0.005, 0.0001, 0.05});

  PoseSamples motion;
  const int samples = data.ConsumeIntegralInRange<int>(0, 12);
  TimeNs time = scan.stamp - data.ConsumeIntegralInRange<TimeNs>(0, 2'000'000'000);
  for (int k = 0; k < samples; ++k) {
    time += data.ConsumeIntegralInRange<TimeNs>(0, 200'000'000);
    const auto pose = mrpt::poses::CPose3D::FromXYZYawPitchRoll(
        anyFloat(data, -50, 50), anyFloat(data, -50, 50), anyFloat(data, -1, 1), anyFloat(data, -7, 7),
        data.ConsumeBool() ? 0.0 : anyFloat(data, -1, 1), data.ConsumeBool() ? 0.0 : anyFloat(data, -1, 1));
    try {
      motion.add(time, pose);
    } catch (const InvalidInput&) {
    }
  }
  const auto mount = mrpt::poses::CPose3D::FromXYZYawPitchRoll(
      anyFloat(data, -1, 1), anyFloat(data, -1, 1), anyFloat(data, -1, 1), anyFloat(data, -7, 7), 0.0, 0.0);
  try {
    validateScan(scan);
    timing.validate();
    const BeamTiming beam_timing = resolveTiming(scan, timing);
    ScanDeskewer deskewer(config);
    DeskewedScan corrected;
    deskewer.deskew(scan, beam_timing, mount, motion, corrected);
    for (const DeskewedPoint& point : corrected.points) {
      check(point.position.allFinite() || !mount.getRotationMatrix().asEigen().allFinite());
    }
    ScanRebinner rebinner;
    RebinnedScan rebinned;
    rebinner.rebin(corrected, {scan.angle_min, scan.angle_increment, scan.ranges.size()}, noReturnValue(scan),
                   rebinned);
    check(rebinned.ranges.size() == scan.ranges.size());
    check(rebinned.intensities.empty() || rebinned.intensities.size() == scan.ranges.size());
  } catch (const InvalidInput&) {
  } catch (const MotionUnavailable&) {
  }
  return 0;
}
