#include "lidar_deskew/core/deskew.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "pose_eigen.h"
#include "simd.h"

namespace lidar_deskew::core {
namespace {

/// Smallest knot interval accepted [s]: bounds the knot count to 1e5 per second of sweep.
constexpr double kMinKnotInterval = 1e-5;
/// [s] Longer knot intervals would overflow the knot loop's time arithmetic and make no sense: a sweep
/// lasts at most max_sweep_duration.
constexpr double kMaxKnotInterval = 1.0;

/// sin(x) and 1 - cos(x), exact to double precision (relative error < 1e-16). Short Taylor series
/// for the small angles knots give (5 rad/s over 5 ms is 0.025 rad), the library beyond. Series
/// coefficients are multiplied, not divided: the compiler may not turn x / c into x * (1 / c).
inline void sinAndVersine(double x, double& sine, double& versine) {
  const double x2 = x * x;
  if (x2 <= 0.05 * 0.05) {
    // next terms: x^9/9! < 6e-18, x^10/10! < 3e-20
    sine = x * (1.0 - x2 * (1.0 / 6) * (1.0 - x2 * (1.0 / 20) * (1.0 - x2 * (1.0 / 42))));
    versine = x2 * 0.5 * (1.0 - x2 * (1.0 / 12) * (1.0 - x2 * (1.0 / 30) * (1.0 - x2 * (1.0 / 56))));
  } else {
    sine = std::sin(x);
    versine = 1.0 - std::cos(x);
  }
}

/// True when `rotation` turns about z only.
bool rotatesAboutZOnly(const Eigen::Matrix3d& rotation) {
  constexpr double kTolerance = 1e-12;
  return std::abs(rotation(0, 2)) <= kTolerance && std::abs(rotation(1, 2)) <= kTolerance &&
         std::abs(rotation(2, 0)) <= kTolerance && std::abs(rotation(2, 1)) <= kTolerance;
}

/// The chain prefix ^L T_R (+) (fixed->base @ t_ref)^-1, composed with MRPT.
mrpt::poses::CPose3D laserFromReferenceBase(TimeNs reference_time, const mrpt::poses::CPose3D& mount,
                                            const MotionSource& motion) {
  return (-mount) + (-motion.basePose(reference_time));
}

/// Exact mode: the whole chain (prefix (+) fixed->base @ t (+) mount) composed with MRPT per point.
class ExactChain {
 public:
  ExactChain(TimeNs reference_time, const mrpt::poses::CPose3D& mount, const MotionSource& motion)
      : prefix_(laserFromReferenceBase(reference_time, mount, motion)), mount_(mount), motion_(motion) {}

  Eigen::Vector3d apply(TimeNs point_time, const Eigen::Vector3d& raw) const {
    const mrpt::poses::CPose3D chain = prefix_ + motion_.basePose(point_time) + mount_;
    Eigen::Vector3d corrected;
    chain.composePoint(raw.x(), raw.y(), raw.z(), corrected.x(), corrected.y(), corrected.z());
    return corrected;
  }

 private:
  mrpt::poses::CPose3D prefix_;
  const mrpt::poses::CPose3D& mount_;
  const MotionSource& motion_;
};

InvalidInput beyondTheFirings(std::size_t count) {
  return InvalidInput("firings", "name a firing beyond the " + std::to_string(count) + " there are");
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// KnotTrajectory

void KnotTrajectory::build(TimeNs origin, double span_begin, double span_end, TimeNs reference_time,
                           double knot_interval, const mrpt::poses::CPose3D& mount,
                           const MotionSource& motion) {
  if (!(knot_interval >= kMinKnotInterval && knot_interval <= kMaxKnotInterval)) {
    throw InvalidInput("knot_interval", "must be in [" + std::to_string(kMinKnotInterval) + ", " +
                                            std::to_string(kMaxKnotInterval) + "] s here");
  }
  if (!(span_end >= span_begin))
    throw InvalidInput("time_offset", "span end before span begin");
  affine_maps_ = false;  // until prepareAffineMaps() on these segments

  // Knot times: both ends and the source's own sample times; and every knot_interval between unless
  // the source's sample times are all there is to its motion (then they reproduce it exactly), or it
  // moves as a screw between them and the motion is planar (then screw segments do).
  const TimeNs begin_time = origin + secondsToNs(span_begin);
  const TimeNs end_time = origin + secondsToNs(span_end);
  const bool screws = motion.screwsBetweenSamples();
  bool grid = !motion.sampleTimesComplete() && !screws;
  std::vector<TimeNs>& times = scratch_times_;
  // Composed in place: each base pose becomes its knot's left factor.
  std::vector<Knot>& knots = scratch_knots_;
  mount_rotation_ = detail::rotationOf(mount);
  mount_translation_ = detail::translationOf(mount);
  for (;;) {
    times.clear();
    times.push_back(begin_time);
    if (grid) {
      const TimeNs step = secondsToNs(knot_interval);
      for (TimeNs t = begin_time + step; t < end_time; t += step)
        times.push_back(t);
    }
    motion.appendSampleTimes(begin_time, end_time, times);
    times.push_back(end_time);
    std::sort(times.begin(), times.end());
    times.erase(std::unique(times.begin(), times.end()), times.end());

    // One motion query per knot (the reference time is usually one of them), then the chain prefix and
    // one MRPT composition per knot.
    knots.resize(times.size());
    for (std::size_t k = 0; k < times.size(); ++k)
      motion.baseTransform(times[k], knots[k].rotation, knots[k].translation);
    const auto reference_knot = std::lower_bound(times.begin(), times.end(), reference_time);
    mrpt::poses::CPose3D base_at_reference;
    if (reference_knot != times.end() && *reference_knot == reference_time) {
      const Knot& knot = knots[static_cast<std::size_t>(reference_knot - times.begin())];
      base_at_reference = detail::poseOf(knot.rotation, knot.translation);
    } else {
      base_at_reference = motion.basePose(reference_time);
    }
    const mrpt::poses::CPose3D laser_from_reference_base = (-mount) + (-base_at_reference);
    const Eigen::Matrix3d prefix_rotation = detail::rotationOf(laser_from_reference_base);
    const Eigen::Vector3d prefix_translation = detail::translationOf(laser_from_reference_base);

    knot_offsets_.resize(times.size());
    for (std::size_t k = 0; k < times.size(); ++k) {
      knot_offsets_[k] = nsToSeconds(times[k] - origin);
      detail::composeInPlace(prefix_rotation, prefix_translation, knots[k].rotation, knots[k].translation);
    }
    planar_ = rotatesAboutZOnly(mount_rotation_);
    for (const Knot& left : knots)
      planar_ = planar_ && rotatesAboutZOnly(left.rotation);
    if (screws && !grid && !planar_) {
      grid = true;  // screw segments are planar here: straight segments between grid knots instead
      continue;
    }
    break;
  }
  const bool screw_segments = planar_ && (screws || motion.screwsBetweenKnots());
  const std::size_t segment_count = std::max<std::size_t>(1, times.size() - 1);
  segments_.resize(segment_count);
  for (std::size_t k = 0; k < segment_count; ++k) {
    Segment& segment = segments_[k];
    const Knot& left = knots[k];
    const Knot& next = knots[std::min(k + 1, times.size() - 1)];
    segment.begin_offset = knot_offsets_[k];
    const double duration = nsToSeconds(times[std::min(k + 1, times.size() - 1)] - times[k]);
    segment.inverse_duration = duration > 0.0 ? 1.0 / duration : 0.0;
    segment.left_rotation = left.rotation;
    segment.left_translation = left.translation;
    segment.translation_step = next.translation - segment.left_translation;
    // R_k^T R_k+1 = left_k^T left_k+1: the left factor R_M^T cancels.
    if (planar_) {
      // Both turn about z only (to 1e-12): the step is its yaw, from the first column of R_k^T R_k+1.
      const double yaw = std::atan2(segment.left_rotation.col(1).dot(next.rotation.col(0)),
                                    segment.left_rotation.col(0).dot(next.rotation.col(0)));
      segment.angle = std::abs(yaw);  // in [0, pi]
      segment.axis = yaw < 0.0 ? Eigen::Vector3d(-Eigen::Vector3d::UnitZ()) : Eigen::Vector3d::UnitZ();
    } else {
      const Eigen::AngleAxisd step_rotation(
          Eigen::Matrix3d(segment.left_rotation.transpose() * next.rotation));
      segment.angle = step_rotation.angle();  // in [0, pi]
      segment.axis = segment.angle > 0.0 ? step_rotation.axis() : Eigen::Vector3d::UnitZ();
    }
    const Eigen::Vector3d rotation_vector = segment.angle * segment.axis;
    segment.left_yaw_cos = segment.left_rotation(0, 0);
    segment.left_yaw_sin = segment.left_rotation(1, 0);
    segment.yaw_step = rotation_vector.z();
    // A screw from knot k to k+1: (R_k+1 - R_k) w = the translation step, w = (Rot(yaw_step) - I)^-1 R_k^T
    // step. Below 1e-9 rad the straight line is the screw to 1e-9 of the step.
    segment.screw = screw_segments && std::abs(segment.yaw_step) > 1e-9;
    segment.screw_offset.setZero();
    if (segment.screw) {
      const Eigen::Vector3d local = segment.left_rotation.transpose() * segment.translation_step;
      const double c = std::cos(segment.yaw_step) - 1.0, s = std::sin(segment.yaw_step);
      const double determinant = c * c + s * s;
      segment.screw_offset = Eigen::Vector3d((c * local.x() + s * local.y()) / determinant,
                                             (-s * local.x() + c * local.y()) / determinant, 0.0);
      segment.translation_step.setZero();
    }
  }
  hint_ = 0;
}

void KnotTrajectory::prepareAffineMaps() {
  for (Segment& segment : segments_) {
    const Eigen::Matrix3d cross = detail::skew(segment.axis);
    const Eigen::Matrix3d left_cross = segment.left_rotation * cross;
    const Eigen::Matrix3d left_cross2 = left_cross * cross;
    segment.rotation_base = segment.left_rotation * mount_rotation_;
    segment.rotation_sine = left_cross * mount_rotation_;
    segment.rotation_versine = left_cross2 * mount_rotation_;
    segment.translation_base = segment.left_rotation * mount_translation_ + segment.left_translation;
    segment.translation_sine = left_cross * (mount_translation_ + segment.screw_offset);
    segment.translation_versine = left_cross2 * (mount_translation_ + segment.screw_offset);
  }
  affine_maps_ = true;
}

std::size_t KnotTrajectory::segmentFor(double time_offset) const {
  std::size_t k = hint_ < segments_.size() ? hint_ : 0;
  while (k + 1 < segments_.size() && time_offset >= knot_offsets_[k + 1])
    ++k;
  while (k > 0 && time_offset < knot_offsets_[k])
    --k;
  hint_ = k;
  return k;
}

Eigen::Vector3d KnotTrajectory::apply(double time_offset, const Eigen::Vector3d& raw) const {
  const Segment& segment = segments_[segmentFor(time_offset)];
  const double fraction =
      std::clamp((time_offset - segment.begin_offset) * segment.inverse_duration, 0.0, 1.0);
  // A screw segment moves the point as if it sat screw_offset further out: p(s) - p_k = R_k (Exp - I) w.
  const Eigen::Vector3d in_base = mount_rotation_ * raw + mount_translation_;
  const Eigen::Vector3d moved = in_base + segment.screw_offset;
  Eigen::Vector3d rotated = in_base;
  if (segment.angle != 0.0) {
    double sine, versine;
    sinAndVersine(fraction * segment.angle, sine, versine);
    const Eigen::Vector3d axis_cross = segment.axis.cross(moved);
    rotated += sine * axis_cross + versine * segment.axis.cross(axis_cross);
  }
  return segment.left_rotation * rotated + segment.left_translation + fraction * segment.translation_step;
}

void KnotTrajectory::transformAt(double time_offset, Eigen::Matrix3d& rotation,
                                 Eigen::Vector3d& translation) const {
  if (!affine_maps_)
    throw std::logic_error("KnotTrajectory::transformAt before prepareAffineMaps()");
  const Segment& segment = segments_[segmentFor(time_offset)];
  const double fraction =
      std::clamp((time_offset - segment.begin_offset) * segment.inverse_duration, 0.0, 1.0);
  // Exp(s angle axis) by Rodrigues, I + sin K + versin K^2, folded into the segment's products.
  double sine = 0.0, versine = 0.0;
  if (segment.angle != 0.0)
    sinAndVersine(fraction * segment.angle, sine, versine);
  rotation = segment.rotation_base + sine * segment.rotation_sine + versine * segment.rotation_versine;
  translation = segment.translation_base + sine * segment.translation_sine +
                versine * segment.translation_versine + fraction * segment.translation_step;
}

namespace {

/// The mount's rotation (row-major, 2 x 2) and translation (x, y) in the plane.
struct PlanarMount {
  double m00, m01, m10, m11, x, y;
};

/// One knot segment's beams [first, end) in the laser frame at the reference time: each beam's rotation
/// (cosine, sine) and translation (in x_out, y_out), as the recurrence left them, turn and move the mounted
/// point, moved by the segment's screw offset; the results replace the translation. Arithmetic alone over
/// arrays (vectorised), in the scalar expression's order, so every lane rounds as one beam at a time would.
LIDAR_DESKEW_AVX2_CLONES void placeBeams(std::size_t first, std::size_t end, const float* __restrict ranges,
                                         const double* __restrict unit, const double* __restrict cosine,
                                         const double* __restrict sine, double* __restrict x_out,
                                         double* __restrict y_out, const PlanarMount mount, double offset_x,
                                         double offset_y) {
  for (std::size_t beam = first; beam < end; ++beam) {
    const double range = ranges[beam];
    const double x = range * unit[2 * beam], y = range * unit[2 * beam + 1];
    const double wx = mount.m00 * x + mount.m01 * y + mount.x + offset_x;
    const double wy = mount.m10 * x + mount.m11 * y + mount.y + offset_y;
    x_out[beam] = cosine[beam] * wx - sine[beam] * wy + x_out[beam];
    y_out[beam] = sine[beam] * wx + cosine[beam] * wy + y_out[beam];
  }
}

/// The per-beam arrays correctPlanarScan() fills: each beam's rotation (cosine, sine) and translation.
struct PlanarBeams {
  double *cosine, *sine, *x, *y, *z;
};

/// A run's beams [from, end) by the recurrence from (cosine, sine, x, y, z) at `from`: serial, each beam's
/// rotation and translation from the last one's.
template <typename Run>
void stepRun(const Run& run, std::size_t from, double cosine, double sine, double x, double y, double z,
             const PlanarBeams& out) {
  for (std::size_t beam = from; beam < run.end; ++beam) {
    out.cosine[beam] = cosine;
    out.sine[beam] = sine;
    out.x[beam] = x;
    out.y[beam] = y;
    out.z[beam] = z;
    const double next_cosine = cosine * run.step_cosine - sine * run.step_sine;
    sine = sine * run.step_cosine + cosine * run.step_sine;
    cosine = next_cosine;
    x += run.step_x;
    y += run.step_y;
    z += run.step_z;
  }
}

/// Two runs' recurrences at once: over their common length one in each SSE2 lane, by stepRun()'s
/// operations (the same bits), so that the two chains of multiplications and additions overlap instead
/// of one waiting on each of its own results; the longer run's rest alone.
template <typename Run>
void stepRuns(const Run& a, const Run& b, const PlanarBeams& out) {
#if defined(__SSE2__)
  const std::size_t common = std::min(a.end - a.first, b.end - b.first);
  __m128d cosine = _mm_set_pd(b.cosine, a.cosine), sine = _mm_set_pd(b.sine, a.sine);
  __m128d x = _mm_set_pd(b.x, a.x), y = _mm_set_pd(b.y, a.y), z = _mm_set_pd(b.z, a.z);
  const __m128d step_cosine = _mm_set_pd(b.step_cosine, a.step_cosine);
  const __m128d step_sine = _mm_set_pd(b.step_sine, a.step_sine);
  const __m128d step_x = _mm_set_pd(b.step_x, a.step_x), step_y = _mm_set_pd(b.step_y, a.step_y);
  const __m128d step_z = _mm_set_pd(b.step_z, a.step_z);
  for (std::size_t i = 0; i < common; ++i) {
    const std::size_t beam_a = a.first + i, beam_b = b.first + i;
    _mm_storel_pd(out.cosine + beam_a, cosine);
    _mm_storeh_pd(out.cosine + beam_b, cosine);
    _mm_storel_pd(out.sine + beam_a, sine);
    _mm_storeh_pd(out.sine + beam_b, sine);
    _mm_storel_pd(out.x + beam_a, x);
    _mm_storeh_pd(out.x + beam_b, x);
    _mm_storel_pd(out.y + beam_a, y);
    _mm_storeh_pd(out.y + beam_b, y);
    _mm_storel_pd(out.z + beam_a, z);
    _mm_storeh_pd(out.z + beam_b, z);
    const __m128d next_cosine = _mm_sub_pd(_mm_mul_pd(cosine, step_cosine), _mm_mul_pd(sine, step_sine));
    sine = _mm_add_pd(_mm_mul_pd(sine, step_cosine), _mm_mul_pd(cosine, step_sine));
    cosine = next_cosine;
    x = _mm_add_pd(x, step_x);
    y = _mm_add_pd(y, step_y);
    z = _mm_add_pd(z, step_z);
  }
  // The longer run's rest (one lane's values).
  const bool a_longer = a.end - a.first > common;
  const Run& rest = a_longer ? a : b;
  const auto lane = [a_longer](__m128d v) {
    return a_longer ? _mm_cvtsd_f64(v) : _mm_cvtsd_f64(_mm_unpackhi_pd(v, v));
  };
  stepRun(rest, rest.first + common, lane(cosine), lane(sine), lane(x), lane(y), lane(z), out);
#else
  stepRun(a, a.first, a.cosine, a.sine, a.x, a.y, a.z, out);
  stepRun(b, b.first, b.cosine, b.sine, b.x, b.y, b.z, out);
#endif
}

/// Beams [first, end), all with a return, as points from `write` on: position (x, y, z)[beam], time offset
/// beam * beam_period - reference_offset, intensity (0 without `intensities`), the beam's index. Four
/// beams at a time as generic vectors (their x y z t rows transposed into the points' fields; with
/// AVX2, one instruction per 4 lanes), the same operations per beam as one at a time; the rest alone.
/// The beam's number as a double counted along (exact: an integer below 2^53).
LIDAR_DESKEW_AVX2_CLONES DeskewedPoint* writeReturnRun(std::size_t first, std::size_t end,
                                                       const double* __restrict x, const double* __restrict y,
                                                       const double* __restrict z,
                                                       const float* __restrict intensities,
                                                       double beam_period, double reference_offset,
                                                       DeskewedPoint* __restrict write) {
  std::size_t beam = first;
  double beam_number = static_cast<double>(beam);
#if LIDAR_DESKEW_VECTOR_SHUFFLES
  using Double4 = double __attribute__((vector_size(32)));
  using Float4 = float __attribute__((vector_size(16)));
  using Index4 = std::uint32_t __attribute__((vector_size(16)));
  using Pairs2 = std::uint64_t __attribute__((vector_size(16)));
  static_assert(sizeof(DeskewedPoint) == 40 && sizeof(Eigen::Vector3d) == 24,
                "a point's x y z time_offset are 4 doubles, its intensity and beam_index 8 bytes");
  if (beam + 4 <= end) {
    Double4 numbers = {beam_number, beam_number + 1.0, beam_number + 2.0, beam_number + 3.0};
    Index4 indices = {static_cast<std::uint32_t>(beam), static_cast<std::uint32_t>(beam + 1),
                      static_cast<std::uint32_t>(beam + 2), static_cast<std::uint32_t>(beam + 3)};
    for (; beam + 4 <= end; beam += 4, write += 4) {
      Double4 xs, ys, zs;
      std::memcpy(&xs, x + beam, sizeof xs);
      std::memcpy(&ys, y + beam, sizeof ys);
      std::memcpy(&zs, z + beam, sizeof zs);
      const Double4 ts = numbers * beam_period - reference_offset;
      const Double4 xy_even = __builtin_shufflevector(xs, ys, 0, 4, 2, 6),
                    xy_odd = __builtin_shufflevector(xs, ys, 1, 5, 3, 7);
      const Double4 zt_even = __builtin_shufflevector(zs, ts, 0, 4, 2, 6),
                    zt_odd = __builtin_shufflevector(zs, ts, 1, 5, 3, 7);
      const Double4 row0 = __builtin_shufflevector(xy_even, zt_even, 0, 1, 4, 5);
      const Double4 row1 = __builtin_shufflevector(xy_odd, zt_odd, 0, 1, 4, 5);
      const Double4 row2 = __builtin_shufflevector(xy_even, zt_even, 2, 3, 6, 7);
      const Double4 row3 = __builtin_shufflevector(xy_odd, zt_odd, 2, 3, 6, 7);
      Float4 values = {};
      if (intensities)
        std::memcpy(&values, intensities + beam, sizeof values);
      const Index4 value_bits = reinterpret_cast<Index4>(values);
      // (intensity, index) of beams 0 1 and of beams 2 3.
      const Pairs2 pairs01 =
          reinterpret_cast<Pairs2>(__builtin_shufflevector(value_bits, indices, 0, 4, 1, 5));
      const Pairs2 pairs23 =
          reinterpret_cast<Pairs2>(__builtin_shufflevector(value_bits, indices, 2, 6, 3, 7));
      const std::uint64_t pair0 = pairs01[0], pair1 = pairs01[1], pair2 = pairs23[0], pair3 = pairs23[1];
      std::memcpy(static_cast<void*>(&write[0]), &row0, sizeof row0);  // x y z time_offset
      std::memcpy(&write[0].intensity, &pair0, sizeof pair0);
      std::memcpy(static_cast<void*>(&write[1]), &row1, sizeof row1);  // x y z time_offset
      std::memcpy(&write[1].intensity, &pair1, sizeof pair1);
      std::memcpy(static_cast<void*>(&write[2]), &row2, sizeof row2);  // x y z time_offset
      std::memcpy(&write[2].intensity, &pair2, sizeof pair2);
      std::memcpy(static_cast<void*>(&write[3]), &row3, sizeof row3);  // x y z time_offset
      std::memcpy(&write[3].intensity, &pair3, sizeof pair3);
      numbers += 4.0;
      indices += 4;
    }
    beam_number = static_cast<double>(beam);
  }
#endif
  for (; beam < end; ++beam, ++write, beam_number += 1.0) {
    write->position = Eigen::Vector3d(x[beam], y[beam], z[beam]);
    write->time_offset = beam_number * beam_period - reference_offset;
    write->intensity = intensities ? intensities[beam] : 0.0f;
    write->beam_index = static_cast<std::uint32_t>(beam);
  }
  return write;
}

}  // namespace

void KnotTrajectory::correctPlanarScan(const PlanarScan& scan, double beam_period,
                                       const std::vector<Eigen::Vector2d>& directions,
                                       double reference_offset, DeskewedScan& out) const {
  const std::size_t count = scan.ranges.size();
  const ReturnTest is_return(scan);
  const float* const ranges = scan.ranges.data();
  const float* const intensities = scan.intensities.empty() ? nullptr : scan.intensities.data();
  const double* const unit = directions.empty() ? nullptr : directions.front().data();
  const PlanarMount mount{mount_rotation_(0, 0), mount_rotation_(0, 1), mount_rotation_(1, 0),
                          mount_rotation_(1, 1), mount_translation_.x(), mount_translation_.y()};
  // Per beam: the rotation's cosine and sine, the translation's x, y (then the point's) and z.
  planar_scratch_.resize(5 * count);
  double* const cosines = planar_scratch_.data();
  double* const sines = cosines + count;
  double* const point_x = sines + count;
  double* const point_y = point_x + count;
  double* const point_z = point_y + count;

  // The knot segments' runs of beams, then their recurrences two at a time, then the points (vectorised).
  planar_runs_.clear();
  std::size_t beam = 0;
  while (beam < count) {
    // The knot segment of this beam, and the beams [beam, end) inside it.
    const double first_offset = static_cast<double>(beam) * beam_period;
    const std::size_t k = segmentFor(first_offset);
    const Segment& segment = segments_[k];
    const double lower = k > 0 ? knot_offsets_[k] : -INFINITY;
    const double upper = k + 2 < knot_offsets_.size() ? knot_offsets_[k + 1] : INFINITY;
    const auto inSegment = [&](std::size_t j) {
      const double offset = static_cast<double>(j) * beam_period;
      return offset >= lower && offset < upper;
    };
    std::size_t end = count;
    if (beam_period != 0.0) {
      const double boundary = (beam_period > 0.0 ? upper : lower) / beam_period;  // beam index at the bound
      if (boundary < static_cast<double>(count))
        end = std::max(beam + 1, static_cast<std::size_t>(boundary));
      while (end > beam + 1 && !inSegment(end - 1))
        --end;
      while (end < count && inSegment(end))
        ++end;
    }
    PlanarRun& run = planar_runs_.emplace_back();
    run.first = beam;
    run.end = end;
    // Rot_z(left_yaw + s yaw_step) at the first beam and its step per beam; the translation
    // left_translation + s translation_step likewise.
    const double fraction_step = beam_period * segment.inverse_duration;
    const double fraction = (first_offset - segment.begin_offset) * segment.inverse_duration;
    double sine, versine;
    sinAndVersine(fraction * segment.yaw_step, sine, versine);
    run.cosine = segment.left_yaw_cos - segment.left_yaw_cos * versine - segment.left_yaw_sin * sine;
    run.sine = segment.left_yaw_sin - segment.left_yaw_sin * versine + segment.left_yaw_cos * sine;
    double step_versine;
    sinAndVersine(fraction_step * segment.yaw_step, run.step_sine, step_versine);
    run.step_cosine = 1.0 - step_versine;
    run.step_x = fraction_step * segment.translation_step.x();
    run.step_y = fraction_step * segment.translation_step.y();
    run.step_z = fraction_step * segment.translation_step.z();
    // Screw segments: R(s) (w + o) + p_k - R_k o, o = screw_offset (0 for straight segments).
    const double offset_x = segment.screw_offset.x(), offset_y = segment.screw_offset.y();
    run.offset_x = offset_x;
    run.offset_y = offset_y;
    run.x = segment.left_translation.x() + fraction * segment.translation_step.x() -
            (segment.left_yaw_cos * offset_x - segment.left_yaw_sin * offset_y);
    run.y = segment.left_translation.y() + fraction * segment.translation_step.y() -
            (segment.left_yaw_sin * offset_x + segment.left_yaw_cos * offset_y);
    run.z = segment.left_translation.z() + fraction * segment.translation_step.z() + mount_translation_.z();
    beam = end;
  }
  const PlanarBeams beams{cosines, sines, point_x, point_y, point_z};
  std::size_t r = 0;
  for (; r + 1 < planar_runs_.size(); r += 2)
    stepRuns(planar_runs_[r], planar_runs_[r + 1], beams);
  if (r < planar_runs_.size()) {
    const PlanarRun& run = planar_runs_[r];
    stepRun(run, run.first, run.cosine, run.sine, run.x, run.y, run.z, beams);
  }
  for (const PlanarRun& run : planar_runs_) {
    placeBeams(run.first, run.end, ranges, unit, cosines, sines, point_x, point_y, mount, run.offset_x,
               run.offset_y);
  }

  // The returns, in beam order, run by run of beams with one.
  out.points.resize(count);  // (resize() only initialises elements beyond the previous size)
  DeskewedPoint* write = out.points.data();
  for (beam = 0; beam < count; ++beam) {  // (the beam after a run has no return)
    const std::size_t run_end = beam + is_return.firstWithout(ranges + beam, count - beam);
    write = writeReturnRun(beam, run_end, point_x, point_y, point_z, intensities, beam_period,
                           reference_offset, write);
    beam = run_end;
  }
  out.points.resize(static_cast<std::size_t>(write - out.points.data()));
}

// ---------------------------------------------------------------------------------------------------

Interpolation parseInterpolation(const std::string& text) {
  if (text == "linear")
    return Interpolation::kLinear;
  if (text == "twist")
    return Interpolation::kTwist;
  throw InvalidInput("interpolation", "must be linear or twist, got '" + text + "'");
}

void DeskewConfig::validate() const {
  if (!std::isfinite(knot_interval) || knot_interval < 0.0 ||
      (knot_interval > 0.0 && (knot_interval < kMinKnotInterval || knot_interval > kMaxKnotInterval))) {
    throw InvalidInput("knot_interval", "must be 0 (exact) or in [" + std::to_string(kMinKnotInterval) +
                                            ", " + std::to_string(kMaxKnotInterval) + "] s, got " +
                                            std::to_string(knot_interval));
  }
  if (!(fit_look_ahead >= 0.0 && fit_look_ahead <= kFitHorizon)) {
    throw InvalidInput("fit_look_ahead", "must be in [0, " + std::to_string(kFitHorizon) + "] s, got " +
                                             std::to_string(fit_look_ahead));
  }
}

float noReturnValue(const PlanarScan& scan, const DeskewedScan& corrected) {
  // Point j is beam j while beams [0, j] all have a return; past the first beam without one, never again.
  const DeskewedPoint* const points = corrected.points.data();
  const auto isOwnBeam = [points](const DeskewedPoint& point) {
    return point.beam_index == static_cast<std::size_t>(&point - points);
  };
  const std::size_t first = static_cast<std::size_t>(
      std::partition_point(points, points + corrected.points.size(), isOwnBeam) - points);
  return first < scan.ranges.size() ? scan.ranges[first] : std::numeric_limits<float>::infinity();
}

PolarPoint toPolar(const Eigen::Vector3d& position) {
  return {std::hypot(position.x(), position.y()), std::atan2(position.y(), position.x())};
}

std::vector<PolarPoint> toPolar(const std::vector<DeskewedPoint>& points) {
  std::vector<PolarPoint> polar;
  polar.reserve(points.size());
  for (const DeskewedPoint& point : points)
    polar.push_back(toPolar(point.position));
  return polar;
}

Eigen::Vector3d deskewPointExact(const Eigen::Vector3d& raw, TimeNs point_time, TimeNs reference_time,
                                 const mrpt::poses::CPose3D& mount, const MotionSource& motion) {
  return ExactChain(reference_time, mount, motion).apply(point_time, raw);
}

ScanDeskewer::ScanDeskewer(const DeskewConfig& config)
    : config_((config.validate(), config)) {}

const MotionSource& ScanDeskewer::motionFor(const MotionSource& motion, TimeNs begin, TimeNs end) {
  if (config_.interpolation == Interpolation::kLinear)
    return motion;
  return twist_.prepare(motion, begin, end, secondsToNs(config_.fit_look_ahead));
}

void ScanDeskewer::updateBeamDirections(const PlanarScan& scan) {
  const std::size_t count = scan.ranges.size();
  if (beam_directions_.size() >= count && grid_angle_min_ == scan.angle_min &&
      grid_angle_increment_ == scan.angle_increment) {
    return;
  }
  grid_angle_min_ = scan.angle_min;
  grid_angle_increment_ = scan.angle_increment;
  beam_directions_.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double angle = static_cast<double>(scan.angle_min) + static_cast<double>(i) * scan.angle_increment;
    beam_directions_[i] = Eigen::Vector2d(std::cos(angle), std::sin(angle));
  }
}

void ScanDeskewer::deskew(const PlanarScan& scan, const BeamTiming& timing, const mrpt::poses::CPose3D& mount,
                          const MotionSource& motion, DeskewedScan& out) {
  try {
    correctScan(scan, timing, mount, motion, out);
  } catch (...) {
    out.points.clear();
    throw;
  }
}

void ScanDeskewer::correctScan(const PlanarScan& scan, const BeamTiming& timing,
                               const mrpt::poses::CPose3D& mount, const MotionSource& motion,
                               DeskewedScan& out) {
  validateScan(scan);
  const std::size_t count = scan.ranges.size();
  if (timing.beam_count != count) {
    out.points.clear();
    throw InvalidInput("ranges", "has " + std::to_string(count) + " beams but the timing was resolved for " +
                                     std::to_string(timing.beam_count));
  }
  out.has_intensities = !scan.intensities.empty();
  out.reference_time = timing.referenceTime(config_.reference);
  const ReturnTest is_return(scan);
  const bool any_return = std::any_of(scan.ranges.begin(), scan.ranges.end(), is_return);
  if (!any_return) {  // nothing to correct: no motion needed
    out.points.clear();
    return;
  }
  updateBeamDirections(scan);
  const double reference_offset = nsToSeconds(out.reference_time - timing.first_beam_time);
  const double last_offset = timing.beamOffset(count - 1);
  const double span_begin = std::min(0.0, last_offset), span_end = std::max(0.0, last_offset);
  const MotionSource& source = motionFor(motion, timing.first_beam_time + secondsToNs(span_begin),
                                         timing.first_beam_time + secondsToNs(span_end));

  // Beam by beam, for the exact mode and for non-planar motion: correct(i, raw point) per return.
  const auto correctEachReturn = [&](auto&& correct) {
    out.points.clear();
    for (std::size_t i = 0; i < count; ++i) {
      const float range = scan.ranges[i];
      if (!is_return(range))
        continue;
      const Eigen::Vector3d raw(range * beam_directions_[i].x(), range * beam_directions_[i].y(), 0.0);
      out.points.push_back({correct(i, raw), timing.beamOffset(i) - reference_offset,
                            out.has_intensities ? scan.intensities[i] : 0.0f, static_cast<std::uint32_t>(i)});
    }
  };

  if (config_.knot_interval == 0.0) {
    const ExactChain chain(out.reference_time, mount, source);
    correctEachReturn(
        [&](std::size_t i, const Eigen::Vector3d& raw) { return chain.apply(timing.beamTime(i), raw); });
    return;
  }

  trajectory_.build(timing.first_beam_time, span_begin, span_end, out.reference_time,
                    source.knotInterval(config_.knot_interval), mount, source);
  if (trajectory_.planar()) {
    trajectory_.correctPlanarScan(scan, timing.beam_period, beam_directions_, reference_offset, out);
    return;
  }
  correctEachReturn([&](std::size_t i, const Eigen::Vector3d& raw) {
    return trajectory_.apply(timing.beamOffset(i), raw);
  });
}

TimeNs ScanDeskewer::deskewFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings,
                                   TimeNs origin, const mrpt::poses::CPose3D& mount,
                                   const MotionSource& motion, std::vector<Eigen::Vector3d>& corrected) {
  try {
    return correctFirings(points, firings, origin, mount, motion, corrected);
  } catch (...) {
    corrected.clear();
    throw;
  }
}

TimeNs ScanDeskewer::deskewPoints(const std::vector<Eigen::Vector3d>& points,
                                  const std::vector<double>& time_offsets, TimeNs origin,
                                  const mrpt::poses::CPose3D& mount, const MotionSource& motion,
                                  std::vector<Eigen::Vector3d>& corrected,
                                  std::vector<double>& corrected_offsets,
                                  std::vector<std::uint32_t>& kept_indices) {
  corrected_offsets.clear();
  kept_indices.clear();
  try {
    if (points.size() != time_offsets.size()) {
      throw InvalidInput("time_offsets", "has " + std::to_string(time_offsets.size()) + " values for " +
                                             std::to_string(points.size()) + " points");
    }
    // The finite points, consecutive ones of one time as one firing.
    kept_points_.clear();
    kept_firings_.clear();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!points[i].allFinite() || !std::isfinite(time_offsets[i]))
        continue;
      if (kept_points_.empty() || kept_firings_.offsets.back() != time_offsets[i])
        kept_firings_.add(time_offsets[i]);
      kept_firings_.of_point.push_back(static_cast<std::uint32_t>(kept_firings_.offsets.size() - 1));
      kept_indices.push_back(static_cast<std::uint32_t>(i));
      kept_points_.push_back(points[i]);
    }
    const TimeNs reference_time =
        correctFirings(kept_points_, kept_firings_, origin, mount, motion, corrected);
    const double exact_reference_offset = nsToSeconds(reference_time - origin);
    corrected_offsets.reserve(kept_indices.size());
    for (std::uint32_t i : kept_indices)
      corrected_offsets.push_back(time_offsets[i] - exact_reference_offset);
    return reference_time;
  } catch (...) {
    corrected.clear();
    corrected_offsets.clear();
    kept_indices.clear();
    throw;
  }
}

TimeNs ScanDeskewer::correctFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings,
                                    TimeNs origin, const mrpt::poses::CPose3D& mount,
                                    const MotionSource& motion, std::vector<Eigen::Vector3d>& corrected) {
  corrected.clear();
  const TimeNs reference_time = beginFirings(points, firings, origin, mount, motion);
  corrected.resize(points.size());
  correctFiringBlock(points, firings, 0, points.size(), corrected.data());
  return reference_time;
}

TimeNs ScanDeskewer::beginFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings,
                                  TimeNs origin, const mrpt::poses::CPose3D& mount, const MotionSource& motion) {
  firing_mount_ = nullptr;
  firing_source_ = nullptr;
  const std::size_t count = firings.offsets.size();
  if (firings.of_point.size() != points.size())
    throw InvalidInput("firings", "give " + std::to_string(firings.of_point.size()) +
                                      " points a firing, not " + std::to_string(points.size()));
  double earliest = INFINITY;
  double latest = -INFINITY;
  for (std::size_t f = 0; f < count; ++f) {
    if (!std::isfinite(firings.offsets[f]))
      throw InvalidInput("firings", "offset " + std::to_string(f) + " is not finite");
    earliest = std::min(earliest, firings.offsets[f]);
    latest = std::max(latest, firings.offsets[f]);
  }
  if (points.empty())
    return origin;
  const double reference_offset = config_.reference == Reference::kStart ? earliest
                                  : config_.reference == Reference::kEnd ? latest
                                                                         : 0.5 * (earliest + latest);
  const TimeNs reference_time = origin + secondsToNs(reference_offset);
  const MotionSource& source =
      motionFor(motion, origin + secondsToNs(earliest), origin + secondsToNs(latest));
  firing_origin_ = origin;
  firing_reference_ = reference_time;
  firing_mount_ = &mount;
  firing_source_ = &source;
  if (config_.knot_interval == 0.0)
    return reference_time;
  trajectory_.build(origin, earliest, latest, reference_time, source.knotInterval(config_.knot_interval),
                    mount, source);
  // The points of one firing share one affine map, built once.
  trajectory_.prepareAffineMaps();
  firing_maps_.resize(count);
  for (std::size_t f = 0; f < count; ++f)
    trajectory_.transformAt(firings.offsets[f], firing_maps_[f].rotation, firing_maps_[f].translation);
  return reference_time;
}

// (also built for AVX2: the same operations in VEX forms, no FMA; 38 -> 31 instructions per point)
LIDAR_DESKEW_AVX2_CLONES void ScanDeskewer::correctFiringBlock(const std::vector<Eigen::Vector3d>& points,
                                                               const Firings& firings, std::size_t begin,
                                                               std::size_t end, Eigen::Vector3d* out) const {
  // (the bounds in locals: the stores below may alias the vectors' members for the compiler, which
  // then reloads them per point)
  const std::size_t count = firings.offsets.size();
  const Eigen::Vector3d* const in = points.data() + begin;
  const std::uint32_t* const firing_of = firings.of_point.data() + begin;
  const std::size_t point_count = end - begin;
  if (point_count == 0)
    return;
  if (config_.knot_interval == 0.0) {
    const double* const offsets = firings.offsets.data();
    const ExactChain chain(firing_reference_, *firing_mount_, *firing_source_);
    for (std::size_t i = 0; i < point_count; ++i) {
      if (firing_of[i] >= count)
        throw beyondTheFirings(count);
      out[i] = chain.apply(firing_origin_ + secondsToNs(offsets[firing_of[i]]), in[i]);
    }
    return;
  }
  const FiringMap* const maps = firing_maps_.data();
  for (std::size_t i = 0; i < point_count; ++i) {
    if (firing_of[i] >= count)
      throw beyondTheFirings(count);
    const FiringMap& map = maps[firing_of[i]];
    out[i].noalias() = map.rotation * in[i] + map.translation;
  }
}

}  // namespace lidar_deskew::core
