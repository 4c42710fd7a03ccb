// Pose samples interpolated like tf2: translation linear, rotation by slerp (closed-form truth); and
// TwistMotion between them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/twist_motion.h"

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

// ---------------------------------------------------------------------------------------------------
// TwistMotion: the twist between samples, fit over neighbours, integrated on SE(3). Truth is closed-form
// (constant twists) or integrated independently here in fine Euler steps on CPose2D.

namespace twist {

CPose3D poseOf(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  mrpt::math::CMatrixDouble33 r(rotation);
  mrpt::math::CVectorFixedDouble<3> t;
  for (int i = 0; i < 3; ++i)
    t[i] = translation[i];
  return CPose3D::FromRotationAndTranslation(r, t);
}

/// start (+) Exp(xi t), closed form through the SE(3) exponential.
CPose3D constantTwist(const CPose3D& start, const Twist& xi, double t) {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  se3Exp(xi * t, rotation, translation);
  return start + poseOf(rotation, translation);
}

/// Largest position difference [m] and angle [rad] between two poses.
double positionError(const CPose3D& a, const CPose3D& b) {
  return std::hypot(std::hypot(a.x() - b.x(), a.y() - b.y()), a.z() - b.z());
}

}  // namespace twist

TEST(TwistMotion, ExponentialIsTheArcAndLogInvertsIt) {
  // 1.5 m/s forward, 2 rad/s about z for 0.3 s: an arc of radius 0.75 m.
  Twist xi;
  xi << 1.5, 0.0, 0.0, 0.0, 0.0, 2.0;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  se3Exp(xi * 0.3, rotation, translation);
  EXPECT_NEAR(translation.x(), 0.75 * std::sin(0.6), 1e-14);
  EXPECT_NEAR(translation.y(), 0.75 * (1.0 - std::cos(0.6)), 1e-14);
  EXPECT_NEAR(std::atan2(rotation(1, 0), rotation(0, 0)), 0.6, 1e-14);
  // A general 3D twist, large and tiny angles.
  for (const double scale : {1.0, 1e-5, 1e-9}) {
    Twist general;
    general << 0.4, -0.2, 0.3, 0.7 * scale, -1.1 * scale, 2.3 * scale;
    se3Exp(general, rotation, translation);
    EXPECT_LT((se3Log(rotation, translation) - general).norm(), 1e-12) << scale;
  }
}

TEST(TwistMotion, ExactForConstantTwistWhereTfsLineIsAChord) {
  // A climbing, turning, rolling motion with samples at 10 Hz.
  Twist xi;
  xi << 2.0, 0.1, 0.3, 0.2, -0.1, 3.0;
  const CPose3D start = CPose3D::FromXYZYawPitchRoll(1.0, -2.0, 0.5, 0.4, 0.05, -0.02);
  PoseSamples samples;
  for (int k = 0; k <= 20; ++k)
    samples.add(kT0 + k * kSecond / 10, twist::constantTwist(start, xi, 0.1 * k));
  TwistMotion motion;
  const TimeNs begin = kT0 + kSecond + kSecond / 40, end = begin + kSecond / 8;
  ASSERT_EQ(&motion.prepare(samples, begin, end), &motion);
  double worst_twist = 0.0, worst_linear = 0.0;
  for (TimeNs t = begin; t <= end; t += kSecond / 200) {
    const CPose3D truth = twist::constantTwist(start, xi, nsToSeconds(t - kT0));
    worst_twist = std::max(worst_twist, twist::positionError(motion.basePose(t), truth));
    worst_linear = std::max(worst_linear, twist::positionError(samples.basePose(t), truth));
  }
  EXPECT_LT(worst_twist, 1e-9);
  EXPECT_GT(worst_linear, 5e-3);  // v w h^2 / 8 = 7.5 mm off the arc
  EXPECT_EQ(motion.estimatedNoise().norm(), 0.0);
}

/// A unicycle whose speed ramps at `acceleration` while turning at `yaw_rate` (which may step at
/// `step_time` to `yaw_rate_after`), integrated in 1 us Euler steps (error ~1e-7 m).
struct Unicycle {
  double speed0, acceleration, yaw_rate, yaw_rate_after, step_time;
  std::vector<CPose2D> integrate(double duration, double dt = 1e-6) const {
    std::vector<CPose2D> poses;
    double x = 0.0, y = 0.0, yaw = 0.0;
    const long steps = std::lround(duration / dt);
    poses.reserve(static_cast<std::size_t>(steps) + 1);
    poses.emplace_back(x, y, yaw);
    for (long i = 0; i < steps; ++i) {
      const double t = (static_cast<double>(i) + 0.5) * dt;
      const double v = speed0 + acceleration * t;
      const double w = t < step_time ? yaw_rate : yaw_rate_after;
      const double mid_yaw = yaw + 0.5 * w * dt;
      x += v * dt * std::cos(mid_yaw);
      y += v * dt * std::sin(mid_yaw);
      yaw += w * dt;
      poses.emplace_back(x, y, yaw);
    }
    return poses;
  }
};

double worstOverSpan(const Unicycle& motion, double sample_period, double begin, double end,
                     double* worst_linear) {
  const double dt = 1e-6;
  const std::vector<CPose2D> truth = motion.integrate(1.0, dt);
  const auto at = [&](double t) { return CPose3D(truth[static_cast<std::size_t>(std::lround(t / dt))]); };
  PoseSamples samples;
  for (double t = 0.0; t <= 1.0 + 1e-9; t += sample_period)
    samples.add(kT0 + secondsToNs(t), at(t));
  TwistMotion fitted;
  fitted.prepare(samples, kT0 + secondsToNs(begin), kT0 + secondsToNs(end));
  double worst = 0.0;
  *worst_linear = 0.0;
  for (double t = begin; t <= end + 1e-9; t += 0.001) {
    const TimeNs time = kT0 + secondsToNs(t);
    worst = std::max(worst, twist::positionError(fitted.basePose(time), at(t)));
    *worst_linear = std::max(*worst_linear, twist::positionError(samples.basePose(time), at(t)));
  }
  return worst;
}

TEST(TwistMotion, FollowsASpeedRampToSecondOrder) {
  // 1 -> 5 m/s at 10 m/s^2 while turning at 3 rad/s, samples at 20 Hz: tf's line is a h^2 / 8 = 3 mm off.
  double worst_linear;
  const double worst = worstOverSpan({1.0, 10.0, 3.0, 3.0, 10.0}, 0.05, 0.3, 0.425, &worst_linear);
  EXPECT_GT(worst_linear, 2e-3);
  EXPECT_LT(worst, 1e-5);
}

TEST(TwistMotion, FollowsAStepOfTurnRateAtASample) {
  // +4 rad/s, then -4 rad/s from a sample on, at 2 m/s with samples at 50 Hz: an arc each side.
  double worst_linear;
  const double worst = worstOverSpan({2.0, 0.0, 4.0, -4.0, 0.4}, 0.02, 0.35, 0.475, &worst_linear);
  EXPECT_GT(worst_linear, 1e-4);
  EXPECT_LT(worst, 1e-6);
}

TEST(TwistMotion, SmoothsNoisyOdometryOverTheWindow) {
  // An arc at 1.5 m/s and 2 rad/s whose odometry has 10 % noise on each 20 ms increment (a random walk).
  // The relative motion over 200 ms sweeps is compared with the true arc's.
  Twist xi;
  xi << 1.5, 0.0, 0.0, 0.0, 0.0, 2.0;
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 0.1);
  PoseSamples samples;
  CPose3D odometry;
  const int steps = 400;  // 8 s
  for (int k = 0; k <= steps; ++k) {
    samples.add(kT0 + k * kSecond / 50, odometry);
    Twist step = xi * 0.02;
    for (int c : {0, 1, 5})
      step[c] *= 1.0 + noise(random);
    odometry = twist::constantTwist(odometry, step, 1.0);
  }
  TwistMotion motion;
  double sum_twist = 0.0, sum_linear = 0.0;
  int count = 0;
  for (int sweep = 0; sweep < 30; ++sweep) {
    const TimeNs begin = kT0 + kSecond + sweep * kSecond / 5 + kSecond / 100, end = begin + kSecond / 5;
    motion.prepare(samples, begin, end);
    EXPECT_GT(motion.estimatedNoise()[5], 0.05);  // 10 % of 2 rad/s is 0.2 rad/s
    EXPECT_LT(motion.estimatedNoise()[5], 0.5);
    const CPose3D twist_start = motion.basePose(begin), linear_start = samples.basePose(begin);
    for (TimeNs t = begin; t <= end; t += kSecond / 100) {
      // The error of the motion since the sweep's start, at a point 3 m ahead.
      const CPose3D truth = twist::constantTwist(CPose3D(), xi, nsToSeconds(t - begin));
      const auto error = [&](const CPose3D& relative) {
        const mrpt::math::TPoint3D a = relative.composePoint({3.0, 0.0, 0.0});
        const mrpt::math::TPoint3D b = truth.composePoint({3.0, 0.0, 0.0});
        return (a - b).norm();
      };
      const double e_twist = error(motion.basePose(t) - twist_start);
      const double e_linear = error(samples.basePose(t) - linear_start);
      sum_twist += e_twist * e_twist;
      sum_linear += e_linear * e_linear;
      ++count;
    }
  }
  const double rms_twist = std::sqrt(sum_twist / count), rms_linear = std::sqrt(sum_linear / count);
  std::printf("noisy odometry, 3 m ahead: twist %.2f mm, linear %.2f mm RMS\n", 1e3 * rms_twist,
              1e3 * rms_linear);
  EXPECT_LT(rms_twist, 0.6 * rms_linear);
}

TEST(TwistMotion, UsesASourceWithoutSamplesAsItIs) {
  PoseSamples samples;
  samples.add(kT0, CPose2D(0.0, 0.0, 0.0));
  samples.add(kT0 + kSecond, CPose2D(1.0, 0.0, 0.5));
  TwistMotion motion;
  // No sample at or after the end: tf beyond its newest sample (extrapolated by its owner).
  EXPECT_EQ(&motion.prepare(samples, kT0 + kSecond / 2, kT0 + 2 * kSecond), &samples);
  EXPECT_EQ(&motion.prepare(samples, kT0 + kSecond / 4, kT0 + kSecond / 2), &motion);
  EXPECT_THROW(motion.basePose(kT0 + 3 * kSecond), MotionUnavailable);
  EXPECT_THROW(TwistMotion(-1.0), InvalidInput);
  EXPECT_THROW(TwistMotion(NAN), InvalidInput);
}

}  // namespace
}  // namespace lidar_deskew::core
