// Pose samples interpolated like tf2: translation linear, rotation by slerp (closed-form truth).
#include <gtest/gtest.h>

#include <cmath>

#include "lidar_deskew/core/motion.h"

namespace lidar_deskew::core {
namespace {

using mrpt::poses::CPose2D;
using mrpt::poses::CPose3D;

constexpr TimeNs kT0 = 1'000'000'000'000;
constexpr TimeNs kSecond = 1'000'000'000;

double wrapAngle(double angle) {
  return std::remainder(angle, 2 * M_PI);
}

TEST(PoseSamples, InterpolatesPlanarPosesLinearlyAndYawAlongTheShortWay) {
  PoseSamples samples;
  samples.add(kT0, CPose2D(0.0, 0.0, 0.0));
  samples.add(kT0 + kSecond, CPose2D(2.0, 1.0, 1.0));
  samples.add(kT0 + 2 * kSecond, CPose2D(2.0, 1.0, -3.0));
  const CPose3D quarter = samples.basePose(kT0 + kSecond / 4);
  EXPECT_NEAR(quarter.x(), 0.5, 1e-12);
  EXPECT_NEAR(quarter.y(), 0.25, 1e-12);
  EXPECT_NEAR(quarter.yaw(), 0.25, 1e-12);
  EXPECT_NEAR(quarter.z(), 0.0, 1e-12);
  // From yaw 1.0 to -3.0: the short way is +2.283 rad (through pi), not -4.0.
  const CPose3D middle = samples.basePose(kT0 + 3 * kSecond / 2);
  EXPECT_NEAR(wrapAngle(middle.yaw() - (1.0 + 0.5 * (2 * M_PI - 4.0))), 0.0, 1e-12);
}

TEST(PoseSamples, ExactAtSamples) {
  PoseSamples samples;
  const CPose3D a = CPose3D::FromXYZYawPitchRoll(1.0, 2.0, 3.0, 0.3, -0.2, 0.1);
  const CPose3D b = CPose3D::FromXYZYawPitchRoll(-1.0, 0.5, 2.0, -0.4, 0.25, 0.0);
  samples.add(kT0, a);
  samples.add(kT0 + 100, b);
  EXPECT_NEAR((samples.basePose(kT0).getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>() -
               a.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>())
                  .asEigen()
                  .norm(),
              0.0, 1e-15);
  EXPECT_NEAR((samples.basePose(kT0 + 100).getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>() -
               b.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>())
                  .asEigen()
                  .norm(),
              0.0, 1e-15);
}

TEST(PoseSamples, SlerpsAboutAFixedAxisAtConstantRate) {
  // Rotation about x by 0 -> 1.2 rad: at 1/3 it is 0.4 rad about x.
  PoseSamples samples;
  samples.add(kT0, CPose3D::FromYawPitchRoll(0.0, 0.0, 0.0));
  samples.add(kT0 + 3 * kSecond, CPose3D::FromYawPitchRoll(0.0, 0.0, 1.2));
  const CPose3D third = samples.basePose(kT0 + kSecond);
  EXPECT_NEAR(third.roll(), 0.4, 1e-12);
  EXPECT_NEAR(third.pitch(), 0.0, 1e-12);
  EXPECT_NEAR(third.yaw(), 0.0, 1e-12);
}

TEST(PoseSamples, NeverExtrapolates) {
  PoseSamples samples;
  EXPECT_THROW(samples.basePose(kT0), MotionUnavailable);
  samples.add(kT0, CPose2D(0, 0, 0));
  EXPECT_NO_THROW(samples.basePose(kT0));
  EXPECT_THROW(samples.basePose(kT0 + 1), MotionUnavailable);
  samples.add(kT0 + kSecond, CPose2D(1, 0, 0));
  EXPECT_THROW(samples.basePose(kT0 - 1), MotionUnavailable);
  EXPECT_THROW(samples.basePose(kT0 + kSecond + 1), MotionUnavailable);
  try {
    samples.basePose(kT0 + 2 * kSecond);
  } catch (const MotionUnavailable& error) {
    EXPECT_EQ(error.time(), kT0 + 2 * kSecond);
  }
}

TEST(PoseSamples, RejectsUnorderedAndNonFiniteSamples) {
  PoseSamples samples;
  samples.add(kT0, CPose2D(0, 0, 0));
  EXPECT_THROW(samples.add(kT0, CPose2D(1, 0, 0)), InvalidInput);
  EXPECT_THROW(samples.add(kT0 - 1, CPose2D(1, 0, 0)), InvalidInput);
  EXPECT_THROW(samples.add(kT0 + 1, CPose3D::FromTranslation(NAN, 0, 0)), InvalidInput);
  EXPECT_EQ(samples.size(), 1u);
}

TEST(PoseSamples, ReportsSampleTimesStrictlyInside) {
  PoseSamples samples;
  for (int k = 0; k < 5; ++k)
    samples.add(kT0 + k * 10, CPose2D(k, 0, 0));
  std::vector<TimeNs> times;
  samples.appendSampleTimes(kT0 + 10, kT0 + 35, times);
  ASSERT_EQ(times.size(), 2u);
  EXPECT_EQ(times[0], kT0 + 20);
  EXPECT_EQ(times[1], kT0 + 30);
}

// Samples at 0, 10, 20, 60, 70 (a 40 ns gap): the gap counts exactly where [begin, end] overlaps it.
TEST(PoseSamples, LongestGapIsTheWidestIntervalOverlappingTheRange) {
  PoseSamples samples;
  for (const TimeNs t : {0, 10, 20, 60, 70})
    samples.add(kT0 + t, CPose2D(static_cast<double>(t), 0, 0));
  EXPECT_EQ(samples.longestGap(kT0 + 30, kT0 + 40), 40);   // inside the gap
  EXPECT_EQ(samples.longestGap(kT0 + 2, kT0 + 8), 10);     // between two close samples
  EXPECT_EQ(samples.longestGap(kT0 + 5, kT0 + 65), 40);    // across the gap
  EXPECT_EQ(samples.longestGap(kT0 + 20, kT0 + 20), 0);    // an instant at a sample: answered exactly
  EXPECT_EQ(samples.longestGap(kT0 + 10, kT0 + 20), 10);   // ends at the gap's first sample
  EXPECT_EQ(samples.longestGap(kT0 + 60, kT0 + 70), 10);   // starts at its last one
  EXPECT_EQ(samples.longestGap(kT0 - 50, kT0 + 5), 10);    // before the samples: not a gap
  EXPECT_EQ(samples.longestGap(kT0 + 65, kT0 + 500), 10);  // after them: not a gap either
  EXPECT_EQ(PoseSamples().longestGap(kT0, kT0 + 10), 0);
}

}  // namespace
}  // namespace lidar_deskew::core
