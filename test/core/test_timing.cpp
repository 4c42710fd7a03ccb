// The timing model (docs/DESIGN.md §4): per-beam times from the message fields and the fallbacks.
#include <gtest/gtest.h>

#include <cmath>

#include "lidar_deskew/core/scan.h"

namespace lidar_deskew::core {
namespace {

constexpr TimeNs kStamp = 1'700'000'000'123'456'789;

PlanarScan makeScan(std::size_t beams, float increment, float time_increment, float scan_time) {
  PlanarScan scan;
  scan.stamp = kStamp;
  scan.angle_min = -static_cast<float>(M_PI);
  scan.angle_increment = increment;
  scan.time_increment = time_increment;
  scan.scan_time = scan_time;
  scan.range_min = 0.1f;
  scan.range_max = 30.0f;
  scan.ranges.assign(beams, 1.0f);
  return scan;
}

TEST(Timing, StampAtStartIsTheFirstBeam) {
  const PlanarScan scan = makeScan(1440, static_cast<float>(2 * M_PI / 1440), 1.0f / 40 / 1440, 0.025f);
  const BeamTiming timing = resolveTiming(scan, TimingConfig());
  EXPECT_EQ(timing.source, TimingSource::kTimeIncrement);
  EXPECT_EQ(timing.first_beam_time, kStamp);
  // beam 1439 at 1439 * time_increment (float), to the nanosecond
  EXPECT_EQ(timing.beamTime(1439),
            kStamp + std::llround(1439 * static_cast<double>(scan.time_increment) * 1e9));
  EXPECT_EQ(timing.earliestBeamTime(), kStamp);
  EXPECT_EQ(timing.latestBeamTime(), timing.beamTime(1439));
  EXPECT_EQ(timing.referenceTime(Reference::kStart), kStamp);
  EXPECT_EQ(timing.referenceTime(Reference::kEnd), timing.beamTime(1439));
  EXPECT_NEAR(static_cast<double>(timing.referenceTime(Reference::kMiddle) - kStamp),
              0.5 * 1439 * static_cast<double>(scan.time_increment) * 1e9, 1.0);
}

TEST(Timing, StampAtEndIsTheLastBeam) {
  const PlanarScan scan = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.125f / 360, 0.125f);
  TimingConfig config;
  config.stamp_at = StampAt::kEnd;
  const BeamTiming timing = resolveTiming(scan, config);
  EXPECT_EQ(timing.beamTime(359), kStamp);
  const double sweep_ns = 359 * static_cast<double>(scan.time_increment) * 1e9;
  EXPECT_NEAR(static_cast<double>(kStamp - timing.first_beam_time), sweep_ns, 1.0);
}

TEST(Timing, NegativeTimeIncrementMeansLaterIndicesWereMeasuredEarlier) {
  const PlanarScan scan = makeScan(100, 0.01f, -1e-4f, 0.0f);
  const BeamTiming start = resolveTiming(scan, TimingConfig());
  // stamp = earliest beam = beam 99; beam 0 is 99 * 1e-4 s later
  EXPECT_EQ(start.earliestBeamTime(), kStamp);
  EXPECT_EQ(start.beamTime(99), kStamp);
  EXPECT_NEAR(static_cast<double>(start.first_beam_time - kStamp), 99 * 1e-4 * 1e9, 2.0);
  TimingConfig at_end;
  at_end.stamp_at = StampAt::kEnd;
  const BeamTiming end = resolveTiming(scan, at_end);
  EXPECT_EQ(end.first_beam_time, kStamp);  // beam 0 is the latest
  EXPECT_EQ(end.latestBeamTime(), kStamp);
}

TEST(Timing, ZeroTimeIncrementFallsBackToScanTimePerRevolution) {
  // 360 deg sensor: scan_time / beams.
  const PlanarScan full = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.0f, 0.2f);
  const BeamTiming timing = resolveTiming(full, TimingConfig());
  EXPECT_EQ(timing.source, TimingSource::kScanTime);
  EXPECT_NEAR(timing.beam_period, 0.2 / 360, 1e-10);
  // 270 deg sensor, 1080 beams at 0.25 deg, 40 Hz: the mirror still turns 2pi per scan_time, so beams
  // are 0.025 / 1440 s apart (not 0.025 / 1080).
  const PlanarScan partial = makeScan(1080, static_cast<float>(1.5 * M_PI / 1080), 0.0f, 0.025f);
  EXPECT_NEAR(resolveTiming(partial, TimingConfig()).beam_period, 0.025 / 1440, 1e-11);
}

TEST(Timing, ZeroTimeIncrementAndScanTimeUseTheConfiguredPeriodOrFail) {
  const PlanarScan scan = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.0f, 0.0f);
  try {
    resolveTiming(scan, TimingConfig());
    FAIL() << "expected InvalidInput";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.field(), "time_increment");
  }
  TimingConfig config;
  config.scan_period = 0.1;
  const BeamTiming timing = resolveTiming(scan, config);
  EXPECT_EQ(timing.source, TimingSource::kScanPeriod);
  EXPECT_NEAR(timing.beam_period, 0.1 / 360, 1e-10);
}

TEST(Timing, AbsurdSweepIsRejected) {
  const PlanarScan scan = makeScan(1440, 0.004f, 0.01f, 0.0f);  // 14.4 s sweep
  try {
    resolveTiming(scan, TimingConfig());
    FAIL() << "expected InvalidInput";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.field(), "time_increment");
  }
}

TEST(Timing, ValidateNamesTheBadField) {
  const auto fieldOf = [](const PlanarScan& scan) -> std::string {
    try {
      validateScan(scan);
    } catch (const InvalidInput& error) {
      return error.field();
    }
    return "";
  };
  PlanarScan scan = makeScan(10, 0.01f, 1e-4f, 0.1f);
  EXPECT_EQ(fieldOf(scan), "");
  scan.angle_increment = NAN;
  EXPECT_EQ(fieldOf(scan), "angle_increment");
  scan.angle_increment = 0.0f;
  EXPECT_EQ(fieldOf(scan), "angle_increment");
  scan.angle_increment = 0.01f;
  scan.angle_min = INFINITY;
  EXPECT_EQ(fieldOf(scan), "angle_min");
  scan.angle_min = 0.0f;
  scan.time_increment = NAN;
  EXPECT_EQ(fieldOf(scan), "time_increment");
  scan.time_increment = 1e-4f;
  scan.intensities.assign(9, 1.0f);
  EXPECT_EQ(fieldOf(scan), "intensities");
  scan.intensities.clear();
  scan.range_max = NAN;
  EXPECT_EQ(fieldOf(scan), "range_max");
  scan.range_max = 30.0f;
  scan.angle_min = 1e30f;  // finite but absurd: would make angle wrapping loop for ever
  EXPECT_EQ(fieldOf(scan), "angle_min");
  scan.angle_min = -13.0f;
  EXPECT_EQ(fieldOf(scan), "angle_min");
  scan.angle_min = -3.0f;
  scan.angle_increment = 7.0f;
  EXPECT_EQ(fieldOf(scan), "angle_increment");
  scan.angle_increment = 0.01f;
  EXPECT_EQ(fieldOf(scan), "");
}

TEST(Timing, ParseNamesAndConfigValidation) {
  EXPECT_EQ(parseReference("middle"), Reference::kMiddle);
  EXPECT_EQ(parseStampAt("end"), StampAt::kEnd);
  EXPECT_THROW(parseReference("centre"), InvalidInput);
  EXPECT_THROW(parseStampAt(""), InvalidInput);
  TimingConfig config;
  config.scan_period = -1.0;
  EXPECT_THROW(config.validate(), InvalidInput);
  config.scan_period = 0.0;
  config.max_sweep_duration = 1e12;  // would overflow nanoseconds
  EXPECT_THROW(config.validate(), InvalidInput);
}

TEST(Timing, TimeOffsetMovesEveryBeamByItsValue) {
  const PlanarScan scan = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.2f / 360, 0.2f);
  TimingConfig config;
  config.time_offset = -0.0375;
  const BeamTiming shifted = resolveTiming(scan, config);
  const BeamTiming plain = resolveTiming(scan, TimingConfig());
  for (std::size_t i : {0u, 100u, 359u})
    EXPECT_EQ(shifted.beamTime(i), plain.beamTime(i) - 37'500'000) << i;
  // Applied before stamp_at: "stamped at the end" equals an offset of minus the sweep.
  TimingConfig at_end;
  at_end.stamp_at = StampAt::kEnd;
  TimingConfig as_offset;
  as_offset.time_offset = -359 * static_cast<double>(scan.time_increment);
  EXPECT_NEAR(static_cast<double>(resolveTiming(scan, at_end).first_beam_time -
                                  resolveTiming(scan, as_offset).first_beam_time),
              0.0, 1.0);
}

TEST(Timing, ReversedBeamOrderPutsTheLastIndexFirstInTime) {
  const PlanarScan scan = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.2f / 360, 0.2f);
  TimingConfig config;
  config.beam_order = BeamOrder::kReversed;
  const BeamTiming timing = resolveTiming(scan, config);
  const double step_ns = static_cast<double>(scan.time_increment) * 1e9;
  // The stamp is still the earliest beam's time: now index 359's.
  EXPECT_EQ(timing.beamTime(359), kStamp);
  EXPECT_NEAR(static_cast<double>(timing.beamTime(0) - kStamp), 359 * step_ns, 2.0);
  EXPECT_NEAR(static_cast<double>(timing.beamTime(100) - kStamp), 259 * step_ns, 2.0);
  config.stamp_at = StampAt::kEnd;  // stamp = the latest beam = index 0
  EXPECT_EQ(resolveTiming(scan, config).beamTime(0), kStamp);
  EXPECT_EQ(parseBeamOrder("reversed"), BeamOrder::kReversed);
  EXPECT_EQ(toString(parseBeamOrder("as_message")), "as_message");
  EXPECT_THROW(parseBeamOrder("backwards"), InvalidInput);
}

TEST(Timing, UseScanPeriodOverridesTheMessagesSpacing) {
  // time_increment in the wrong unit (ms for s) and scan_time wrong too.
  const PlanarScan scan = makeScan(360, static_cast<float>(2 * M_PI / 360), 0.2f / 360 * 1000, 0.5f);
  TimingConfig config;
  config.scan_period = 0.2;
  config.use_scan_period = true;
  const BeamTiming timing = resolveTiming(scan, config);
  EXPECT_EQ(timing.source, TimingSource::kScanPeriodSet);
  EXPECT_NEAR(timing.beam_period, 0.2 / 360, 1e-10);  // the float angle increment
  EXPECT_NEAR(nsToSeconds(timing.latestBeamTime() - timing.earliestBeamTime()), 359 * 0.2 / 360, 1e-8);
  // Without it the message's ms value makes an absurd sweep: refused.
  EXPECT_THROW(resolveTiming(scan, TimingConfig()), InvalidInput);
  TimingConfig without_period;
  without_period.use_scan_period = true;
  try {
    without_period.validate();
    ADD_FAILURE() << "use_scan_period without scan_period accepted";
  } catch (const InvalidInput& error) {
    EXPECT_EQ(error.field(), "use_scan_period");
  }
  TimingConfig far;
  far.time_offset = 61.0;
  EXPECT_THROW(far.validate(), InvalidInput);
}

}  // namespace
}  // namespace lidar_deskew::core
