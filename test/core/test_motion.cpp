// Pose samples interpolated like tf2: translation linear, rotation by slerp (closed-form truth); and
// TwistMotion between them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/twist_motion.h"
#include "../../src/core/kth_smallest.h"
#include "../../src/core/pose_eigen.h"

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

TEST(PoseEigen, ComposesAsMrptsComposeFromBitForBit) {
  // The knots compose their poses without CPose3D: the same bits as MRPT's composeFrom (Eigen's own
  // product of column-major matrices differs in about 4 of 5 random cases), large and tiny angles.
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> angle(-3.2, 3.2), position(-100.0, 100.0), tiny(-1e-4, 1e-4);
  int differing = 0;
  for (int i = 0; i < 20000; ++i) {
    const bool small = i % 2 == 0;
    const CPose3D a = CPose3D::FromXYZYawPitchRoll(position(random), position(random), position(random),
                                                   angle(random), small ? tiny(random) : angle(random),
                                                   small ? tiny(random) : angle(random));
    CPose3D b = CPose3D::FromXYZYawPitchRoll(position(random), position(random), position(random), angle(random),
                                             small ? tiny(random) : angle(random), angle(random));
    Eigen::Matrix3d rotation = detail::rotationOf(b);
    Eigen::Vector3d translation = detail::translationOf(b);
    detail::composeInPlace(detail::rotationOf(a), detail::translationOf(a), rotation, translation);
    b.composeFrom(a, b);
    const Eigen::Matrix3d mrpt_rotation = detail::rotationOf(b);
    const Eigen::Vector3d mrpt_translation = detail::translationOf(b);
    differing += std::memcmp(rotation.data(), mrpt_rotation.data(), sizeof(double) * 9) != 0 ||
                 std::memcmp(translation.data(), mrpt_translation.data(), sizeof(double) * 3) != 0;
  }
  EXPECT_EQ(differing, 0);
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

/// A climbing, turning, rolling motion of constant twist, sampled at 10 Hz for 2 s from kT0.
struct ClimbingTurn {
  Twist xi = (Twist() << 2.0, 0.1, 0.3, 0.2, -0.1, 3.0).finished();
  CPose3D start = CPose3D::FromXYZYawPitchRoll(1.0, -2.0, 0.5, 0.4, 0.05, -0.02);
  PoseSamples samples;

  ClimbingTurn() {
    for (int k = 0; k <= 20; ++k)
      samples.add(kT0 + k * kSecond / 10, constantTwist(start, xi, 0.1 * k));
  }
  CPose3D truth(TimeNs t) const { return constantTwist(start, xi, nsToSeconds(t - kT0)); }
};

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
  const twist::ClimbingTurn turn;
  const PoseSamples& samples = turn.samples;
  TwistMotion motion;
  const TimeNs begin = kT0 + kSecond + kSecond / 40, end = begin + kSecond / 8;
  ASSERT_EQ(&motion.prepare(samples, begin, end), &motion);
  double worst_twist = 0.0, worst_linear = 0.0;
  for (TimeNs t = begin; t <= end; t += kSecond / 200) {
    const CPose3D truth = turn.truth(t);
    worst_twist = std::max(worst_twist, twist::positionError(motion.basePose(t), truth));
    worst_linear = std::max(worst_linear, twist::positionError(samples.basePose(t), truth));
  }
  EXPECT_LT(worst_twist, 1e-9);
  EXPECT_GT(worst_linear, 5e-3);  // v w h^2 / 8 = 7.5 mm off the arc
  EXPECT_EQ(motion.estimatedNoise().norm(), 0.0);
}

TEST(TwistMotion, AnswersInAnyOrderAsInTimeOrder) {
  // baseTransform() looks from the piece asked last: answers asked backwards and skipping pieces are
  // the bits of those asked forwards, and of basePose().
  const twist::ClimbingTurn turn;
  TwistMotion motion;
  const TimeNs begin = kT0 + kSecond + kSecond / 40, end = begin + 5 * kSecond / 8;
  motion.prepare(turn.samples, begin, end);
  std::vector<TimeNs> times;
  for (TimeNs t = begin; t <= end; t += kSecond / 300)
    times.push_back(t);
  std::vector<Eigen::Matrix<double, 3, 4>> forwards;
  for (const TimeNs t : times) {
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    motion.baseTransform(t, rotation, translation);
    forwards.emplace_back();
    forwards.back() << rotation, translation;
  }
  std::vector<std::size_t> order;
  for (std::size_t i = times.size(); i-- > 0;)
    order.push_back(i);
  for (std::size_t i = 0; i < times.size(); i += 37)
    order.push_back(i);
  for (const std::size_t i : order) {
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
    motion.baseTransform(times[i], rotation, translation);
    Eigen::Matrix<double, 3, 4> again;
    again << rotation, translation;
    EXPECT_EQ(std::memcmp(again.data(), forwards[i].data(), sizeof(double) * 12), 0) << "at " << times[i];
    const CPose3D pose = motion.basePose(times[i]);
    again << pose.getRotationMatrix().asEigen(), Eigen::Vector3d(pose.x(), pose.y(), pose.z());
    EXPECT_EQ(std::memcmp(again.data(), forwards[i].data(), sizeof(double) * 12), 0) << "at " << times[i];
  }
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

/// A unicycle whose speed and turn rate follow cosines (the smooth drives of sim::smoothScenarios):
/// speed v cos(2 pi t / 2 s), turn rate w cos(2 pi t / 1.3 s), from the origin at t = 0, integrated by
/// the classical Runge-Kutta method in 10 us steps (error ~1e-13 m).
struct SmoothUnicycle {
  double v, w;
  std::vector<CPose2D> integrate(double duration, double dt) const {
    const auto derivative = [&](double t, const Eigen::Vector3d& state) {
      const double speed = v * std::cos(M_PI * t);
      return Eigen::Vector3d(speed * std::cos(state.z()), speed * std::sin(state.z()),
                             w * std::cos(2.0 * M_PI * t / 1.3));
    };
    std::vector<CPose2D> poses;
    Eigen::Vector3d state = Eigen::Vector3d::Zero();
    const long steps = std::lround(duration / dt);
    for (long i = 0; i <= steps; ++i) {
      poses.emplace_back(state.x(), state.y(), state.z());
      const double t = static_cast<double>(i) * dt;
      const Eigen::Vector3d k1 = derivative(t, state), k2 = derivative(t + dt / 2, state + dt / 2 * k1);
      const Eigen::Vector3d k3 = derivative(t + dt / 2, state + dt / 2 * k2);
      const Eigen::Vector3d k4 = derivative(t + dt, state + dt * k3);
      state += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    return poses;
  }
};

/// RMS error [m] over [begin, end] of a point 5 m ahead of and 0.25 m beside the base (a laser's return)
/// with the motion fitted from exact samples every `sample_period` [s], and tf's line (`linear`).
double smoothError(const std::vector<CPose2D>& truth, double dt, double sample_period, double begin,
                   double end, double* linear) {
  const auto at = [&](double t) { return CPose3D(truth[static_cast<std::size_t>(std::lround(t / dt))]); };
  PoseSamples samples;
  const long count = std::lround(std::floor(2.0 / sample_period));
  for (long k = 0; k <= count; ++k)
    samples.add(kT0 + secondsToNs(k * sample_period), at(k * sample_period));
  TwistMotion fitted;
  fitted.prepare(samples, kT0 + secondsToNs(begin), kT0 + secondsToNs(end));
  // Exact samples: what the noise estimate finds is the motion's own curvature (up to 1e-4 rad/s at
  // 40 Hz), far below a hundredth of the turn rate, so the slopes are fitted.
  EXPECT_LT(fitted.estimatedNoise()[5], 1e-3) << sample_period;
  double sum = 0.0, sum_linear = 0.0;
  int n = 0;
  const mrpt::math::TPoint3D point(5.0, 0.25, 0.0);
  for (double t = begin; t <= end + 1e-9; t += 0.001) {
    const TimeNs time = kT0 + secondsToNs(t);
    const mrpt::math::TPoint3D truth_point = at(t).composePoint(point);
    sum += (fitted.basePose(time).composePoint(point) - truth_point).sqrNorm();
    sum_linear += (samples.basePose(time).composePoint(point) - truth_point).sqrNorm();
    ++n;
  }
  *linear = std::sqrt(sum_linear / n);
  return std::sqrt(sum / n);
}

TEST(TwistMotion, ThirdOrderOnATwistChangingBetweenSamples) {
  // 6 m/s and 5 rad/s peaks; a 0.2 s sweep across the speed's zero (at 0.5 s) and the turn rate's
  // steepest change (0.325 s). Samples at 10, 20, 40, 80 Hz: tf's line is second order (error / 4 per
  // halving), the fit third order (/ 8).
  const double dt = 1e-5;
  const std::vector<CPose2D> truth = SmoothUnicycle{6.0, 5.0}.integrate(2.0, dt);
  double previous = 0.0, previous_linear = 0.0;
  for (const double period : {0.1, 0.05, 0.025, 0.0125}) {
    double linear;
    const double error = smoothError(truth, dt, period, 0.3, 0.5, &linear);
    std::printf("smooth unicycle, samples every %.4f s: twist %.4f mm, linear %.4f mm RMS 5 m ahead\n",
                period, 1e3 * error, 1e3 * linear);
    EXPECT_LT(error, 0.2 * linear) << period;
    if (previous > 0.0) {
      EXPECT_NEAR(previous_linear / linear, 4.0, 1.0) << period;
      EXPECT_GT(previous / error, 6.0) << period;
    }
    previous = error;
    previous_linear = linear;
  }
}

/// Odometry with 10 % noise on each component of each 20 ms increment (a random walk, as the simulator's
/// --odom-noise) of a base whose body twist is `twist_at(t)`, integrated in 1 ms steps (the truth). The
/// RMS error [m] of the motion since each of 30 sweeps' start (200 ms each), at a point 3 m ahead: the
/// twist fit's and tf's line's.
template <class TwistAt>
void noisySweepErrors(TwistAt twist_at, unsigned seed, double& rms_twist, double& rms_linear,
                      double look_ahead = 0.0) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::vector<CPose3D> truth(1);  // every 1 ms for 8 s
  for (int i = 0; i < 8000; ++i)
    truth.push_back(twist::constantTwist(truth.back(), twist_at(i * 1e-3 + 5e-4), 1e-3));
  PoseSamples samples;
  CPose3D odometry;
  for (int k = 0; k <= 400; ++k) {
    samples.add(kT0 + k * kSecond / 50, odometry);
    if (k == 400)
      break;
    const CPose3D step = truth[static_cast<std::size_t>(20 * k + 20)] - truth[static_cast<std::size_t>(20 * k)];
    Twist increment = se3Log(step.getRotationMatrix().asEigen(), Eigen::Vector3d(step.x(), step.y(), step.z()));
    for (int c : {0, 1, 5})
      increment[c] *= 1.0 + noise(random);
    odometry = twist::constantTwist(odometry, increment, 1.0);
  }
  TwistMotion motion;
  double sum_twist = 0.0, sum_linear = 0.0;
  int count = 0;
  for (int sweep = 0; sweep < 30; ++sweep) {
    const TimeNs begin = kT0 + kSecond + sweep * kSecond / 5 + kSecond / 100, end = begin + kSecond / 5;
    motion.prepare(samples, begin, end, secondsToNs(look_ahead));
    EXPECT_GT(motion.estimatedNoise()[5], 0.02);
    const CPose3D twist_start = motion.basePose(begin), linear_start = samples.basePose(begin);
    const std::size_t first = static_cast<std::size_t>((begin - kT0) / 1'000'000);
    for (TimeNs t = begin; t <= end; t += kSecond / 100) {
      const CPose3D relative = truth[static_cast<std::size_t>((t - kT0) / 1'000'000)] - truth[first];
      const auto error = [&](const CPose3D& fitted) {
        return (fitted.composePoint({3.0, 0.0, 0.0}) - relative.composePoint({3.0, 0.0, 0.0})).norm();
      };
      const double e_twist = error(motion.basePose(t) - twist_start);
      const double e_linear = error(samples.basePose(t) - linear_start);
      sum_twist += e_twist * e_twist;
      sum_linear += e_linear * e_linear;
      ++count;
    }
  }
  rms_twist = std::sqrt(sum_twist / count);
  rms_linear = std::sqrt(sum_linear / count);
}

// Noisy odometry: where one line explains the means of the sweep's intervals and as many before within
// the estimated noise (strictly: residuals below 0.7 of its variance), the sweep follows that line, else
// the samples. On an arc (1.5 m/s, 2 rad/s) that averages the noise out; on a drive whose speed and turn
// rate change all the time (the smooth drives' cosines at their high speeds) a line through the
// curving twist is biased the same way over the whole sweep, so it must stay close to following the
// samples (within 5 %), from the samples up to the sweep's end only (SweepsMotionDoesNotDependOnTheTfAfterIt).
TEST(TwistMotion, NoisyOdometryAveragedWhereALineExplainsTheSweep) {
  double arc_sum = 0.0, arc_linear_sum = 0.0;
  for (const unsigned seed : {7u, 8u, 9u}) {
    double arc_twist, arc_linear, smooth_twist, smooth_linear;
    noisySweepErrors([](double) { return (Twist() << 1.5, 0.0, 0.0, 0.0, 0.0, 2.0).finished(); }, seed,
                     arc_twist, arc_linear);
    noisySweepErrors(
        [](double t) {
          return (Twist() << 6.0 * std::cos(M_PI * t), 0.0, 0.0, 0.0, 0.0, 5.0 * std::cos(2.0 * M_PI * t / 1.3))
              .finished();
        },
        seed, smooth_twist, smooth_linear);
    std::printf("noisy odometry (seed %u), 3 m ahead: arc twist %.2f mm, linear %.2f; smooth drive twist %.2f, "
                "linear %.2f mm RMS\n",
                seed, 1e3 * arc_twist, 1e3 * arc_linear, 1e3 * smooth_twist, 1e3 * smooth_linear);
    EXPECT_LT(arc_twist, 1.05 * arc_linear) << seed;        // measured 0.86-1.02
    EXPECT_LT(smooth_twist, 1.05 * smooth_linear) << seed;  // measured 1.00-1.04
    arc_sum += arc_twist;
    arc_linear_sum += arc_linear;
  }
  EXPECT_LT(arc_sum, 0.95 * arc_linear_sum);  // measured 0.92
}

// With a look-ahead of 0.2 s (as long as the sweeps) the line is fit over a window centred on the sweep:
// on the arc the noise averages out further than from one side, and on the smooth drive it stays within
// 5 % of following the samples, tf's line (each seed, as without it).
TEST(TwistMotion, NoisyOdometryWithALookAheadAveragesBothSides) {
  double ahead_sum = 0.0, behind_sum = 0.0, linear_sum = 0.0;
  for (const unsigned seed : {7u, 8u, 9u}) {
    double ahead, behind, linear, smooth_ahead, smooth_linear;
    const auto arc = [](double) { return (Twist() << 1.5, 0.0, 0.0, 0.0, 0.0, 2.0).finished(); };
    noisySweepErrors(arc, seed, ahead, linear, 0.2);
    noisySweepErrors(arc, seed, behind, linear, 0.0);
    noisySweepErrors(
        [](double t) {
          return (Twist() << 6.0 * std::cos(M_PI * t), 0.0, 0.0, 0.0, 0.0, 5.0 * std::cos(2.0 * M_PI * t / 1.3))
              .finished();
        },
        seed, smooth_ahead, smooth_linear, 0.2);
    std::printf("noisy odometry (seed %u), look-ahead 0.2 s: arc %.2f mm (without %.2f, linear %.2f); smooth "
                "drive %.2f (linear %.2f) mm RMS\n",
                seed, 1e3 * ahead, 1e3 * behind, 1e3 * linear, 1e3 * smooth_ahead, 1e3 * smooth_linear);
    EXPECT_LT(ahead, 1.05 * linear) << seed;
    EXPECT_LT(smooth_ahead, 1.05 * smooth_linear) << seed;
    ahead_sum += ahead;
    behind_sum += behind;
    linear_sum += linear;
  }
  EXPECT_LT(ahead_sum, behind_sum);
}

/// Odometry at 50 Hz for 4 s of a twist constant over each 20 ms step (`twist_at(step)`): its heading
/// from the travel of two wheels `base` [m] apart, each counted in whole ticks of `tick` [m] (0: exact),
/// and each step's turn and advance off by normal noise of `sigma` [rad/s, m/s] in their means; the
/// truth beside it, both as PoseSamples.
template <class TwistAt>
void steppedOdometry(TwistAt twist_at, double tick, double base, double sigma, unsigned seed,
                     PoseSamples& odometry, PoseSamples& truth, double jitter = 0.0) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::uniform_real_distribution<double> stamp_error(-jitter, jitter);
  CPose3D true_pose, noisy_pose;
  double travel = 0.0, heading = 0.0;  // the base's path length [m] and turn [rad] so far
  for (int k = 0; k <= 200; ++k) {
    CPose3D reported = noisy_pose;
    if (tick > 0.0) {
      const double right = std::round((travel + 0.5 * base * heading) / tick);
      const double left = std::round((travel - 0.5 * base * heading) / tick);
      reported.setYawPitchRoll((right - left) * tick / base, 0.0, 0.0);
    }
    odometry.add(kT0 + k * kSecond / 50 + (jitter > 0.0 ? secondsToNs(stamp_error(random)) : 0), reported);
    truth.add(kT0 + k * kSecond / 50, true_pose);
    const Twist twist = twist_at(k);
    true_pose = twist::constantTwist(true_pose, twist, 0.02);
    Twist noisy = twist;
    if (sigma > 0.0) {
      noisy[0] += noise(random);
      noisy[5] += noise(random);
    }
    noisy_pose = twist::constantTwist(noisy_pose, noisy, 0.02);
    travel += 0.02 * noisy[0];
    heading += 0.02 * noisy[5];
  }
}

/// RMS error [m] of a point 5 m ahead of the base over sweeps of 0.1 s in the middle 2 s, relative to
/// each sweep's start, with the twist fit (1 s look-ahead) and tf's line (`linear`); the median over the
/// sweeps of the fit's estimated turn-rate noise (`noise`).
double steppedErrors(const PoseSamples& odometry, const PoseSamples& truth, double* linear, double* noise) {
  TwistMotion motion;
  double sum = 0.0, sum_linear = 0.0;
  int n = 0;
  std::vector<double> noises;
  const mrpt::math::TPoint3D point(5.0, 0.0, 0.0);
  for (int sweep = 0; sweep < 20; ++sweep) {
    const TimeNs begin = kT0 + kSecond + sweep * kSecond / 10 + kSecond / 200, end = begin + kSecond / 10;
    motion.prepare(odometry, begin, end, kSecond);
    noises.push_back(motion.estimatedNoise()[5]);
    const CPose3D start = motion.basePose(begin), linear_start = odometry.basePose(begin);
    const CPose3D true_start = truth.basePose(begin);
    for (TimeNs t = begin; t <= end; t += kSecond / 1000) {
      const mrpt::math::TPoint3D true_point = (truth.basePose(t) - true_start).composePoint(point);
      sum += ((motion.basePose(t) - start).composePoint(point) - true_point).sqrNorm();
      sum_linear += ((odometry.basePose(t) - linear_start).composePoint(point) - true_point).sqrNorm();
      ++n;
    }
  }
  std::nth_element(noises.begin(), noises.begin() + 10, noises.end());
  *noise = noises[10];
  *linear = std::sqrt(sum_linear / n);
  return std::sqrt(sum / n);
}

// The noise estimate must not take motion for noise, nor noise for less than it is. A turn rate
// stepping +-4 rad/s every other sample (ILD26TRI/varying), its heading from wheels counted in 1 mm
// ticks on a 0.235 m wheel base: the ticks leave the means 0.21 rad/s apart in each pair (one
// wheel's tick over 20 ms), and the estimate must stay well below the alternation (taking the
// alternation for noise, 3.5 rad/s, made the fit 33 times worse than tf's line); with jittered
// stamps, the spline is refused. Normal noise of 0.2 rad/s per step on an arc: found within 0.6-1.4
// of it, and smoothed.
TEST(TwistMotion, NoiseEstimateTellsASteppingTurnRateFromNoise) {
  PoseSamples odometry, truth;
  steppedOdometry([](int k) { return (Twist() << 1.0, 0.0, 0.0, 0.0, 0.0, (k / 2) % 2 ? -4.0 : 4.0).finished(); },
                  0.001, 0.235, 0.0, 1, odometry, truth);
  double linear, noise;
  const double stepped = steppedErrors(odometry, truth, &linear, &noise);
  std::printf("stepping turn rate, quantised heading: fit %.2f mm, tf's line %.2f mm, noise %.3f rad/s\n",
              1e3 * stepped, 1e3 * linear, noise);
  EXPECT_LT(noise, 1.0);
  EXPECT_LT(stepped, 1.05 * linear);
  // Stamps off by up to 5 ms (a driver stamping on receipt): noise of 2-2.7 rad/s against the steps'
  // 8, which a smooth spline would take for noise (2-5 times tf's line's error, were it accepted).
  for (const unsigned seed : {1u, 2u, 3u, 4u}) {
    PoseSamples jittered, jitter_truth;
    steppedOdometry([](int k) { return (Twist() << 1.0, 0.0, 0.0, 0.0, 0.0, (k / 2) % 2 ? -4.0 : 4.0).finished(); },
                    0.0, 0.0, 0.0, seed, jittered, jitter_truth, 0.005);
    double jitter_linear, jitter_noise;
    const double jitter_fit = steppedErrors(jittered, jitter_truth, &jitter_linear, &jitter_noise);
    std::printf("stepping turn rate, stamps +-5 ms (seed %u): fit %.2f mm, tf's line %.2f mm, noise %.3f\n", seed,
                1e3 * jitter_fit, 1e3 * jitter_linear, jitter_noise);
    EXPECT_LT(jitter_fit, 1.05 * jitter_linear) << seed;
  }
  for (const unsigned seed : {1u, 2u, 3u}) {
    PoseSamples noisy, arc;
    steppedOdometry([](int) { return (Twist() << 1.5, 0.0, 0.0, 0.0, 0.0, 2.0).finished(); }, 0.0, 0.0, 0.2,
                    seed, noisy, arc);
    double noisy_linear, estimated;
    const double fitted = steppedErrors(noisy, arc, &noisy_linear, &estimated);
    std::printf("arc, noise 0.2 (seed %u): fit %.2f mm, tf's line %.2f mm, noise %.3f\n", seed,
                1e3 * fitted, 1e3 * noisy_linear, estimated);
    EXPECT_GT(estimated, 0.6 * 0.2) << seed;
    EXPECT_LT(estimated, 1.4 * 0.2) << seed;
    EXPECT_LT(fitted, noisy_linear) << seed;
  }
}

// A sweep is corrected as soon as tf covers it, live and offline, and tf after that arrives in whatever
// amounts the network or the bag gives. The fit must not depend on it: the same sweep prepared from the
// samples up to the one closing it, and from samples two seconds further, gives the same motion to the
// bit, with exact samples of a twist changing between them and with noisy ones (the noise estimated
// and smoothed).
TEST(TwistMotion, SweepsMotionDoesNotDependOnTheTfAfterIt) {
  std::mt19937 random(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  for (const bool noisy : {false, true}) {
    PoseSamples all;
    std::vector<std::pair<TimeNs, CPose3D>> poses;
    CPose3D odometry;
    for (int k = 0; k <= 250; ++k) {  // 5 s at 50 Hz, speed and turn rate changing all the time
      const double t = k * 0.02;
      poses.emplace_back(kT0 + k * kSecond / 50, odometry);
      Twist step = Twist::Zero();
      step[0] = 0.02 * 1.5 * std::cos(M_PI * t);
      step[5] = 0.02 * 2.0 * std::sin(2.0 * M_PI * t / 1.3);
      if (noisy) {
        for (int c : {0, 5})
          step[c] *= 1.0 + noise(random);
      }
      odometry = twist::constantTwist(odometry, step, 1.0);
    }
    for (const auto& [time, pose] : poses)
      all.add(time, pose);
    int compared = 0;
    for (int sweep = 0; sweep < 10; ++sweep) {
      const TimeNs begin = kT0 + 2 * kSecond + sweep * kSecond / 8 + 3'000'000, end = begin + kSecond / 8;
      PoseSamples covering;  // up to the first sample at or after the sweep's end
      for (const auto& [time, pose] : poses) {
        covering.add(time, pose);
        if (time >= end)
          break;
      }
      TwistMotion early, late;
      early.prepare(covering, begin, end);
      late.prepare(all, begin, end);
      if (noisy) {
        EXPECT_GT(late.estimatedNoise()[5], 0.05) << sweep;  // the noisy branch is the one tested
      } else {
        EXPECT_LT(late.estimatedNoise()[5], 5e-5) << sweep;  // below the floor (1e-6 rad per 20 ms): exact
      }
      for (TimeNs t = begin; t <= end; t += kSecond / 500) {
        const CPose3D a = early.basePose(t), b = late.basePose(t);
        EXPECT_EQ(a.x(), b.x()) << noisy << " " << sweep << " " << t;
        EXPECT_EQ(a.y(), b.y()) << noisy << " " << sweep << " " << t;
        EXPECT_EQ(a.yaw(), b.yaw()) << noisy << " " << sweep << " " << t;
        ++compared;
      }
    }
    EXPECT_EQ(compared, 10 * 63);
  }
}

// With a look-ahead L the fit of noisy samples also reads the samples after the sweep up to end + L,
// and nothing after: prepared from the samples up to the first at or after end + L, from samples two
// seconds further, and by one TwistMotion fed them in pieces (prepared as each 0.1 s arrives, as tf
// comes), the sweep's motion is the same to the bit, exact samples or noisy ones; and it differs from
// the fit without a look-ahead (centred stencils, the noise averaged on both sides).
TEST(TwistMotion, LookAheadReadsTheSamplesUpToItOnly) {
  constexpr TimeNs kLookAhead = 3 * kSecond / 10;
  std::mt19937 random(11);
  std::normal_distribution<double> noise(0.0, 0.1);
  for (const bool noisy : {false, true}) {
    std::vector<std::pair<TimeNs, CPose3D>> poses;
    CPose3D odometry;
    for (int k = 0; k <= 300; ++k) {  // 6 s at 50 Hz on an arc whose speed changes
      const double t = k * 0.02;
      poses.emplace_back(kT0 + k * kSecond / 50, odometry);
      Twist step = Twist::Zero();
      step[0] = 0.02 * (1.5 + 0.5 * std::cos(M_PI * t));
      step[5] = 0.02 * 2.0;
      if (noisy) {
        for (int c : {0, 5})
          step[c] *= 1.0 + noise(random);
      }
      odometry = twist::constantTwist(odometry, step, 1.0);
    }
    PoseSamples all;
    for (const auto& [time, pose] : poses)
      all.add(time, pose);
    int compared = 0, changed = 0;
    for (int sweep = 0; sweep < 10; ++sweep) {
      const TimeNs begin = kT0 + 2 * kSecond + sweep * kSecond / 5 + 3'000'000, end = begin + kSecond / 5;
      PoseSamples covering;  // up to the first sample at or after end + look-ahead
      for (const auto& [time, pose] : poses) {
        covering.add(time, pose);
        if (time >= end + kLookAhead)
          break;
      }
      PoseSamples growing;  // the same samples, arriving in pieces of 0.1 s
      TwistMotion early, late, in_pieces, without;
      std::size_t next = 0;
      for (TimeNs arrived = end; next < poses.size() && poses[next].first <= end + kLookAhead + kSecond / 10;
           arrived += kSecond / 10) {
        for (; next < poses.size() && poses[next].first <= arrived; ++next)
          growing.add(poses[next].first, poses[next].second);
        in_pieces.prepare(growing, begin, end, kLookAhead);
      }
      early.prepare(covering, begin, end, kLookAhead);
      late.prepare(all, begin, end, kLookAhead);
      without.prepare(all, begin, end);
      EXPECT_EQ(late.estimatedNoise()[5] > 0.02, noisy) << sweep;  // the branch meant is the one tested
      for (TimeNs t = begin; t <= end; t += kSecond / 500) {
        const CPose3D a = early.basePose(t), b = late.basePose(t), c = in_pieces.basePose(t);
        for (const CPose3D* other : {&a, &c}) {
          EXPECT_EQ(other->x(), b.x()) << noisy << " " << sweep << " " << t;
          EXPECT_EQ(other->y(), b.y()) << noisy << " " << sweep << " " << t;
          EXPECT_EQ(other->yaw(), b.yaw()) << noisy << " " << sweep << " " << t;
        }
        const CPose3D d = without.basePose(t);
        changed += d.x() != b.x() || d.yaw() != b.yaw() ? 1 : 0;
        ++compared;
      }
    }
    EXPECT_EQ(compared, 10 * 101);
    EXPECT_GT(changed, noisy ? compared / 2 : 0);  // the look-ahead is used (exact: centred stencils)
  }
}

// The fit keeps work across sweeps (each interval's mean twist and smallest noise residual, with the
// samples they were computed from) and reads the samples' times only through their differences. So one
// TwistMotion prepared sweep after sweep, as the node and deskew_bag use it, gives to the bit what a fresh
// one gives for each sweep, and what a fresh one gives with every time shifted by an odd number of
// nanoseconds (another epoch): poses and noise estimates. Exact and noisy samples, jittered spacing (as
// tf from a real driver has), and a jump back in time (a bag played in a loop).
TEST(TwistMotion, KeptWorkGivesTheFitAFreshOneGives) {
  constexpr TimeNs kShift = 1'699'999'000'123'456'789;
  std::mt19937 random(5);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::uniform_int_distribution<TimeNs> jitter(-3'000'000, 3'000'000);
  for (const bool noisy : {false, true}) {
    PoseSamples samples, shifted;
    CPose3D odometry;
    TimeNs previous = 0;
    for (int k = 0; k <= 400; ++k) {  // 8 s at about 50 Hz, speed and turn rate changing all the time
      const TimeNs offset = k * kSecond / 50 + jitter(random);
      const double h = k == 0 ? 0.02 : nsToSeconds(offset - previous);
      const double t = nsToSeconds(offset) - 0.5 * h;  // the interval's middle
      Twist step = Twist::Zero();
      step[0] = h * 1.5 * std::cos(M_PI * t);
      step[1] = h * 0.2 * std::sin(3.0 * t);
      step[5] = h * 2.0 * std::sin(2.0 * M_PI * t / 1.3);
      if (noisy) {
        for (int c : {0, 1, 5})
          step[c] *= 1.0 + noise(random);
      }
      odometry = twist::constantTwist(odometry, step, 1.0);
      samples.add(kT0 + offset, odometry);
      shifted.add(kShift + offset, odometry);
      previous = offset;
    }
    TwistMotion kept;
    int compared = 0;
    // 40 sweeps of 0.1 s from 1.2 s on, then the first 10 again (time goes back).
    for (int n = 0; n < 50; ++n) {
      const TimeNs begin = 12 * kSecond / 10 + (n % 40) * kSecond / 10 + 1'234'567, end = begin + kSecond / 10;
      TwistMotion fresh, fresh_shifted;
      EXPECT_EQ(&kept.prepare(samples, kT0 + begin, kT0 + end), &kept);
      fresh.prepare(samples, kT0 + begin, kT0 + end);
      fresh_shifted.prepare(shifted, kShift + begin, kShift + end);
      for (int c = 0; c < 6; ++c) {
        EXPECT_EQ(kept.estimatedNoise()[c], fresh.estimatedNoise()[c]) << noisy << " " << n << " " << c;
        EXPECT_EQ(fresh_shifted.estimatedNoise()[c], fresh.estimatedNoise()[c]) << noisy << " " << n << " " << c;
      }
      if (n == 30) {  // the branch meant is the one tested
        EXPECT_EQ(fresh.estimatedNoise()[5] > 0.02, noisy) << fresh.estimatedNoise()[5];
        EXPECT_EQ(fresh.estimatedNoise()[5] < 5e-5, !noisy);
      }
      for (TimeNs t = begin; t <= end; t += kSecond / 400) {
        const CPose3D a = kept.basePose(kT0 + t), b = fresh.basePose(kT0 + t);
        const CPose3D c = fresh_shifted.basePose(kShift + t);
        for (const CPose3D* other : {&a, &c}) {
          EXPECT_EQ(other->x(), b.x()) << noisy << " " << n << " " << t;
          EXPECT_EQ(other->y(), b.y()) << noisy << " " << n << " " << t;
          EXPECT_EQ(other->yaw(), b.yaw()) << noisy << " " << n << " " << t;
        }
        ++compared;
      }
    }
    EXPECT_EQ(compared, 50 * 41);
  }
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
}

// The twist fit's and the re-binner's medians: kthSmallest gives, bit for bit, what std::nth_element puts
// at k, whatever its first pivot (none, a value among them, one between) and wherever k lies, near either
// end of the values (one pass) or inside (partitions first), with ties and infinities among them.
TEST(KthSmallest, IsWhatNthElementPutsAtK) {
  std::mt19937_64 random(7);
  std::vector<double> buffer;
  for (int trial = 0; trial < 20000; ++trial) {
    const std::size_t n = 1 + random() % 60;
    std::vector<double> values(n);
    const int kind = static_cast<int>(random() % 3);
    for (double& value : values) {
      value = kind == 0   ? static_cast<double>(random() % 4)  // many ties
              : kind == 1 ? std::uniform_real_distribution<double>(0.0, 1.0)(random)
                          : (random() % 6 == 0 ? INFINITY : static_cast<double>(random() % 100));
    }
    const std::size_t k = random() % n;
    const int pivot = static_cast<int>(random() % 3);
    double guess = pivot == 0 ? NAN : values[random() % n] + (pivot == 1 ? 0.0 : 0.5);
    std::vector<double> sorted = values;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), sorted.end());
    const double* const data = values.data();
    const double found =
        detail::kthSmallest(n, k, [data](std::size_t i) { return data[i]; }, buffer, guess);
    ASSERT_EQ(std::memcmp(&found, &sorted[k], sizeof found), 0) << "n " << n << " k " << k;
    ASSERT_EQ(std::memcmp(&guess, &found, sizeof found), 0);
  }
}

}  // namespace
}  // namespace lidar_deskew::core
