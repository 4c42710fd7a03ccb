// Degenerate input: a clear error or an empty result, never NaN points, never a crash.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "lidar_deskew/core/rebin.h"
#include "support/truth.h"

namespace lidar_deskew::core {
namespace {

constexpr TimeNs kStamp = 1'700'000'000'000'000'000;

PlanarScan smallScan(std::vector<float> ranges) {
  PlanarScan scan;
  scan.stamp = kStamp;
  scan.angle_min = -1.0f;
  scan.angle_increment = 0.1f;
  scan.time_increment = 1e-4f;
  scan.scan_time = 0.1f;
  scan.range_min = 0.1f;
  scan.range_max = 20.0f;
  scan.ranges = std::move(ranges);
  return scan;
}

/// A robot driving at 1 m/s along x, sampled over [stamp - 1 s, stamp + 1 s].
PoseSamples drivingSamples() {
  PoseSamples samples;
  for (int k = -10; k <= 10; ++k) {
    samples.add(kStamp + k * 100'000'000, mrpt::poses::CPose2D(0.1 * k, 0.0, 0.0));
  }
  return samples;
}

std::string invalidField(const std::function<void()>& action) {
  try {
    action();
  } catch (const InvalidInput& error) {
    return error.field();
  }
  return "";
}

TEST(Degenerate, EmptyScanGivesAnEmptyResultWithoutNeedingMotion) {
  const PlanarScan scan = smallScan({});
  const PoseSamples no_motion;
  ScanDeskewer deskewer;
  DeskewedScan out;
  deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), no_motion, out);
  EXPECT_TRUE(out.points.empty());
  EXPECT_EQ(out.reference_time, kStamp);
  ScanRebinner rebinner;
  RebinnedScan rebinned;
  rebinner.rebin(out, {scan.angle_min, scan.angle_increment, 0}, 0.0f, rebinned);
  EXPECT_TRUE(rebinned.ranges.empty());
}

TEST(Degenerate, AllBeamsInvalidGiveNoPointsAndAllNoReturnBins) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const PlanarScan scan = smallScan({nan, inf, -inf, 0.0f, 0.05f, 25.0f, -1.0f});
  const PoseSamples no_motion;  // not needed: nothing to correct
  ScanDeskewer deskewer;
  DeskewedScan out;
  deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), no_motion, out);
  EXPECT_TRUE(out.points.empty());
  ScanRebinner rebinner;
  RebinnedScan rebinned;
  const float no_return = noReturnValue(scan);
  EXPECT_TRUE(std::isnan(no_return));
  rebinner.rebin(out, {scan.angle_min, scan.angle_increment, scan.ranges.size()}, no_return, rebinned);
  ASSERT_EQ(rebinned.ranges.size(), scan.ranges.size());
  for (float range : rebinned.ranges)
    EXPECT_TRUE(std::isnan(range));
}

TEST(Degenerate, OneBeam) {
  const PlanarScan scan = smallScan({2.0f});
  const PoseSamples samples = drivingSamples();
  for (const double knot_interval : {0.005, 0.0}) {
    DeskewConfig config;
    config.knot_interval = knot_interval;
    config.reference = Reference::kEnd;
    ScanDeskewer deskewer(config);
    DeskewedScan out;
    deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), samples, out);
    ASSERT_EQ(out.points.size(), 1u);
    EXPECT_NEAR(out.points[0].position.x(), 2.0 * std::cos(-1.0), 1e-6);
    EXPECT_NEAR(out.points[0].position.y(), 2.0 * std::sin(-1.0), 1e-6);
    EXPECT_EQ(out.points[0].time_offset, 0.0);
  }
}

TEST(Degenerate, NonFiniteRangesAreSkippedAndNoPointIsNaN) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const PlanarScan scan = smallScan({1.0f, nan, 2.0f, inf, 3.0f, -inf, 4.0f});
  const PoseSamples samples = drivingSamples();
  ScanDeskewer deskewer;
  DeskewedScan out;
  deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), samples, out);
  ASSERT_EQ(out.points.size(), 4u);
  const std::uint32_t expected_beams[] = {0, 2, 4, 6};
  for (std::size_t j = 0; j < 4; ++j) {
    EXPECT_EQ(out.points[j].beam_index, expected_beams[j]);
    EXPECT_TRUE(out.points[j].position.allFinite());
    // driving 1 m/s: beam i at i * 0.1 ms is seen from 0.1 i mm further along x
    const double angle = -1.0 + 0.1 * expected_beams[j];
    const double range = 1.0 + j;
    EXPECT_NEAR(out.points[j].position.x(), range * std::cos(angle) + 1e-4 * expected_beams[j], 1e-6);
  }
  ScanRebinner rebinner;
  RebinnedScan rebinned;
  rebinner.rebin(out, {scan.angle_min, scan.angle_increment, scan.ranges.size()}, noReturnValue(scan),
                 rebinned);
  ASSERT_EQ(rebinned.ranges.size(), scan.ranges.size());
  // The four returns are lone (0.1 rad apart at 1-4 m: never one surface): each stays in its bin.
  for (std::size_t j = 0; j < 4; ++j) {
    EXPECT_NEAR(rebinned.ranges[expected_beams[j]], 1.0 + j, 1e-3);
  }
}

// The no-return value read off the corrected points is the one the ranges give: the first beam without a
// return (here each a different value), wherever it lies, +inf when there is none.
TEST(Degenerate, NoReturnValueFromTheCorrectedPointsIsTheFirstMiss) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const PoseSamples samples = drivingSamples();
  const std::vector<std::pair<std::vector<float>, float>> cases = {
      {{1.0f, 2.0f, 3.0f, 4.0f, 5.0f}, inf},
      {{0.05f, 2.0f, 3.0f, 0.0f, 5.0f}, 0.05f},
      {{1.0f, 25.0f, 3.0f, 0.0f, 5.0f}, 25.0f},
      {{1.0f, 2.0f, 3.0f, 4.0f, -1.0f}, -1.0f},
      {{1.0f, 2.0f, 3.0f, 0.0f, 0.05f, 6.0f}, 0.0f},
      {{1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f, 8.0f, inf}, inf},
      {{0.0f, 0.01f}, 0.0f},
      {{2.0f}, inf},
      {{}, inf}};
  for (const double knot_interval : {0.005, 0.0}) {
    DeskewConfig config;
    config.knot_interval = knot_interval;
    ScanDeskewer deskewer(config);
    for (const auto& [ranges, expected] : cases) {
      const PlanarScan scan = smallScan(ranges);
      DeskewedScan out;
      deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), samples, out);
      EXPECT_EQ(noReturnValue(scan, out), expected) << ranges.size() << " beams";
      EXPECT_EQ(noReturnValue(scan), expected) << ranges.size() << " beams";
    }
    PlanarScan scan = smallScan({1.0f, 2.0f, nan, 4.0f});
    DeskewedScan out;
    deskewer.deskew(scan, resolveTiming(scan, {}), mrpt::poses::CPose3D(), samples, out);
    EXPECT_TRUE(std::isnan(noReturnValue(scan, out)));
  }
}

TEST(Degenerate, MismatchedFieldsAreNamed) {
  const PoseSamples samples = drivingSamples();
  ScanDeskewer deskewer;
  DeskewedScan out;
  PlanarScan scan = smallScan({1.0f, 2.0f, 3.0f});
  const BeamTiming timing = resolveTiming(scan, {});
  scan.intensities = {1.0f, 2.0f};
  EXPECT_EQ(invalidField([&] { deskewer.deskew(scan, timing, mrpt::poses::CPose3D(), samples, out); }),
            "intensities");
  scan.intensities.clear();
  scan.ranges.push_back(4.0f);  // timing resolved for 3 beams
  EXPECT_EQ(invalidField([&] { deskewer.deskew(scan, timing, mrpt::poses::CPose3D(), samples, out); }),
            "ranges");
  scan.angle_increment = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(invalidField([&] { deskewer.deskew(scan, timing, mrpt::poses::CPose3D(), samples, out); }),
            "angle_increment");
  EXPECT_TRUE(out.points.empty());

  std::vector<Eigen::Vector3d> points(3, Eigen::Vector3d::Zero()), corrected;
  std::vector<double> offsets(2, 0.0), corrected_offsets;
  std::vector<std::uint32_t> kept;
  EXPECT_EQ(invalidField([&] {
              deskewer.deskewPoints(points, offsets, kStamp, mrpt::poses::CPose3D(), samples, corrected,
                                    corrected_offsets, kept);
            }),
            "time_offsets");

  DeskewConfig config;
  config.knot_interval = -0.001;
  EXPECT_EQ(invalidField([&] { ScanDeskewer bad(config); }), "knot_interval");
  config.knot_interval = NAN;
  EXPECT_EQ(invalidField([&] { ScanDeskewer bad(config); }), "knot_interval");
  ScanRebinner rebinner;
  RebinnedScan rebinned;
  EXPECT_EQ(invalidField([&] { rebinner.rebin(out, {0.0f, 0.0f, 5}, 0.0f, rebinned); }), "angle_increment");
}

TEST(Degenerate, AbsurdGridAnglesEndPromptly) {
  // The re-binner is also public API: a grid far from +-pi must not make angle wrapping loop.
  DeskewedScan points;
  points.points.push_back({Eigen::Vector3d(2.0, 0.0, 0.0), 0.0, 0.0f, 0});
  points.points.push_back({Eigen::Vector3d(2.0, 0.1, 0.0), 0.0, 0.0f, 1});
  ScanRebinner rebinner;
  RebinnedScan out;
  rebinner.rebin(points, {1e30f, 0.05f, 3}, 0.0f, out);
  EXPECT_EQ(out.ranges.size(), 3u);
  EXPECT_EQ(invalidField([&] { rebinner.rebin(points, {0.0f, 100.0f, 3}, 0.0f, out); }), "angle_increment");
}

TEST(Degenerate, PointsThatAreAllNonFiniteGiveAnEmptyResult) {
  const PoseSamples no_motion;
  ScanDeskewer deskewer;
  std::vector<Eigen::Vector3d> points(4, Eigen::Vector3d(NAN, 0, 0)), corrected;
  std::vector<double> offsets(4, 0.0), corrected_offsets;
  std::vector<std::uint32_t> kept;
  deskewer.deskewPoints(points, offsets, kStamp, mrpt::poses::CPose3D(), no_motion, corrected,
                        corrected_offsets, kept);
  EXPECT_TRUE(corrected.empty());
  EXPECT_TRUE(kept.empty());
}

}  // namespace
}  // namespace lidar_deskew::core
