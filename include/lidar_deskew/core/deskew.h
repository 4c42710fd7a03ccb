// The correction of paper eq. 1-7 (docs/DESIGN.md §4 conventions, §5 knots): every beam re-expressed in the
// laser frame at the reference time.
//
//   ^L P = ( ^L T_R  (+)  ^R T_R'(t_i)  (+)  ^R' T_L' ) . ^L' P
//
// ^R T_L is the mount (base -> laser), ^R T_R'(t_i) = (fixed->base @ t_ref)^-1 (+) (fixed->base @ t_i)
// the base motion from the reference time to the beam's time, ^L' P the raw beam (eq. 6).
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include "lidar_deskew/core/motion.h"
#include "lidar_deskew/core/scan.h"
#include "lidar_deskew/core/twist_motion.h"

namespace lidar_deskew::core {

/// How the base moves between the motion source's samples.
enum class Interpolation {
  kLinear,  ///< as tf2 answers: translation linear, rotation by slerp (a chord where the robot drives an arc)
  kTwist    ///< TwistMotion: the twist between samples, fit over their neighbours, integrated on SE(3)
};
/// Parses "linear" | "twist". Throws InvalidInput("interpolation") otherwise.
Interpolation parseInterpolation(const std::string& text);

struct DeskewConfig {
  /// The time all points are re-expressed at.
  Reference reference = Reference::kStart;
  /// Motion between the source's samples (a source without sample times is used as it answers).
  Interpolation interpolation = Interpolation::kTwist;
  /// [s] spacing of the interpolation knots: the motion source is queried at the sweep's first and
  /// last beam, at its own sample times (MotionSource::appendSampleTimes) and, unless those are all
  /// of its motion (MotionSource::sampleTimesComplete), every knot_interval between; beams between
  /// knots use the interpolated relative motion.
  /// 0 = exact mode: one motion query and one MRPT composition per beam (for verification).
  double knot_interval = 0.005;
  /// [s] interpolation twist: the fit of noisy samples also reads the source's samples after the
  /// sweep's end up to end + fit_look_ahead (TwistMotion::prepare). 0 = only up to the sample closing
  /// the sweep. The result depends on the samples up to that time only.
  double fit_look_ahead = 0.0;

  /// Throws InvalidInput("knot_interval") when negative, not finite, or outside [1e-5, 1] s (0 = exact);
  /// InvalidInput("fit_look_ahead") when negative, not finite or over kFitHorizon (1 s).
  void validate() const;
};

/// One corrected return.
struct DeskewedPoint {
  Eigen::Vector3d position;  ///< [m] in the laser frame at the reference time
  double time_offset;        ///< [s] beam time - reference time
  float intensity;           ///< the beam's intensity; 0 when the scan has none
  std::uint32_t beam_index;  ///< index of the beam in the input scan
};

/// A corrected scan: the returns only (beams without a return are dropped, never NaN), in beam order.
struct DeskewedScan {
  TimeNs reference_time = 0;  ///< [ns]
  bool has_intensities = false;
  std::vector<DeskewedPoint> points;
};

/// noReturnValue(scan) (rebin.h) from `corrected`, the correction of `scan`: its points are the returns
/// in beam order, so the first beam without one is the first point whose beam index is not its own
/// position (found by bisection, without reading the ranges again).
float noReturnValue(const PlanarScan& scan, const DeskewedScan& corrected);

/// Points grouped by firing time: point i was measured at origin + offsets[of_point[i]]. A
/// multi-line LIDAR fires a column of points at once: they share a firing, whatever their order.
struct Firings {
  std::vector<double> offsets;          ///< [s] from the origin, one per firing
  std::vector<std::uint32_t> of_point;  ///< the firing of each point

  void clear() {
    offsets.clear();
    of_point.clear();
  }
  /// Adds a firing at `offset` [s]; returns its index.
  std::uint32_t add(double offset) {
    offsets.push_back(offset);
    return static_cast<std::uint32_t>(offsets.size() - 1);
  }
};

/// Polar form of a corrected point in the laser's x-y plane (paper eq. 7, with atan2).
struct PolarPoint {
  double range;    ///< [m] sqrt(x^2 + y^2)
  double bearing;  ///< [rad] atan2(y, x) in (-pi, pi]; 0 for the origin
};
PolarPoint toPolar(const Eigen::Vector3d& position);
/// Polar form of every point, in the same order.
std::vector<PolarPoint> toPolar(const std::vector<DeskewedPoint>& points);

/// The base motion relative to the reference time, sampled at knots and interpolated between them
/// (lerp + slerp, like tf2), folded together with the mount so that one call maps a raw laser-frame
/// point at a time offset to the laser frame at the reference time. The chain at each knot is composed
/// with MRPT; applying it between knots is plain arithmetic.
class KnotTrajectory {
 public:
  /// Queries `motion` at the knots covering [origin + span_begin, origin + span_end] (offsets in [s])
  /// and at `reference_time`; composes ^L T_R (+) ^R T_R'(t_k) with `mount` (base -> laser).
  /// Throws MotionUnavailable when the source does not cover a knot or the reference time.
  void build(TimeNs origin, double span_begin, double span_end, TimeNs reference_time, double knot_interval,
             const mrpt::poses::CPose3D& mount, const MotionSource& motion);

  /// The raw point `raw` [m] (laser frame at time origin + time_offset [s]) in the laser frame at the
  /// reference time. `time_offset` must lie in the span given to build(). Not thread-safe: it keeps
  /// a hint of the last knot segment used (consecutive calls with close times are O(1)).
  Eigen::Vector3d apply(double time_offset, const Eigen::Vector3d& raw) const;

  /// What apply() does at `time_offset`, as one affine map: apply(t, q) = rotation q + translation
  /// (to rounding). For the points of one firing time (a multi-line LIDAR's column) it is built once.
  /// Needs prepareAffineMaps() after build().
  void transformAt(double time_offset, Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) const;
  /// Folds each knot segment's motion and the mount into the products transformAt() reads (the planar
  /// path and apply() do not need them, so build() leaves them out).
  void prepareAffineMaps();

  /// True when the mount and every knot's motion rotate about z only (a planar robot with an upright
  /// laser): then correctPlanarScan() applies.
  bool planar() const { return planar_; }

  /// apply() to every return of a scan whose beam i lies at angle direction `directions[i]` and time
  /// offset i * beam_period [s] from the origin; replaces out.points with them (time offsets relative
  /// to `reference_offset` [s]), in beam order. Precondition: planar(). Within a knot segment
  /// the rotation advances by a fixed step per beam, so no trigonometry runs per beam; the result
  /// equals apply() to ~1e-12 m.
  void correctPlanarScan(const PlanarScan& scan, double beam_period,
                         const std::vector<Eigen::Vector2d>& directions, double reference_offset,
                         DeskewedScan& out) const;

  std::size_t knotCount() const { return knot_offsets_.size(); }

 private:
  /// Between knots k and k+1 (fraction s in [0, 1]) a raw laser point q maps to
  ///   R_M^T (R(s) (R_M q + p_M) + p(s) - p_M),  R(s) = R_k Exp(s angle axis),  p(s) = p_k + s (p_k+1 - p_k)
  /// = left_rotation Exp(s angle axis) w + left_translation + s translation_step,  w = R_M q + p_M,
  /// with (left_rotation, left_translation) = (-mount) (+) rel_k and translation_step = R_M^T (p_k+1 - p_k);
  /// rel_k = ^R T_R'(t_k) and (R_M, p_M) the mount.
  struct Segment {
    double begin_offset;      // [s] knot k, from the origin
    double inverse_duration;  // [1/s]; 0 for the single-knot case
    Eigen::Matrix3d left_rotation;
    Eigen::Vector3d left_translation;  // [m]
    Eigen::Vector3d translation_step;  // [m]
    Eigen::Vector3d axis;              // unit axis of R_k^T R_k+1 (any unit vector when angle = 0)
    double angle;                      // [rad] in [0, pi]
    // planar case: left_rotation = Rot_z(left_yaw), Exp(s angle axis) = Rot_z(s yaw_step)
    double left_yaw_cos, left_yaw_sin;
    double yaw_step;  // [rad] signed
    // screw segments (the source moves with a constant body twist between knots, planar): p(s) = p_k +
    // (R(s) - R_k) screw_offset instead of the straight line; translation_step is then 0.
    bool screw = false;
    Eigen::Vector3d screw_offset = Eigen::Vector3d::Zero();  // [m], in the frame of left_translation
    // transformAt(): with K the cross-product matrix of the axis, sin and versin of s angle,
    //   rotation    = left_rotation (I + sin K + versin K^2) R_M = rotation_base + sin rotation_sine + versin
    //   rotation_versine translation = left_rotation (I + sin K + versin K^2) p_M + left_translation + s
    //   translation_step
    Eigen::Matrix3d rotation_base, rotation_sine, rotation_versine;
    Eigen::Vector3d translation_base, translation_sine, translation_versine;  // [m]
  };
  std::size_t segmentFor(double time_offset) const;
  /// correctPlanarScan()'s beams [first, end) of one knot segment: the rotation (cosine, sine) and the
  /// translation (x, y, z) at the first, their steps per beam, and the segment's screw offset.
  struct PlanarRun {
    std::size_t first, end;
    double cosine, sine, step_cosine, step_sine;
    double x, y, z, step_x, step_y, step_z;
    double offset_x, offset_y;
  };

  std::vector<double> knot_offsets_;   // [s] from the origin, strictly increasing
  std::vector<Segment> segments_;      // one per knot pair (one, degenerate, for a single knot)
  Eigen::Matrix3d mount_rotation_;     // R_M, base <- laser
  Eigen::Vector3d mount_translation_;  // p_M [m]
  bool planar_ = false;
  bool affine_maps_ = false;  // prepareAffineMaps() since build()
  mutable std::size_t hint_ = 0;
  mutable std::vector<double> planar_scratch_;  // correctPlanarScan()'s per-beam values
  mutable std::vector<PlanarRun> planar_runs_;  // and its runs
  std::vector<TimeNs> scratch_times_;
  /// build()'s base poses at the knots, composed in place into the knots' left factors.
  struct Knot {
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
  };
  std::vector<Knot> scratch_knots_;
};

/// Corrects planar scans and point sets. Keeps caches between calls (beam directions of the last
/// angle grid, knot buffers), so reuse one instance per input stream. Not thread-safe.
class ScanDeskewer {
 public:
  /// Throws InvalidInput when the config is invalid.
  explicit ScanDeskewer(const DeskewConfig& config = DeskewConfig());

  const DeskewConfig& config() const { return config_; }

  /// Corrects one scan whose per-beam times are `timing` (from resolveTiming on the same scan).
  /// `mount` is the laser's pose on the base (base -> laser). Beams without a return are skipped.
  /// Throws InvalidInput for an invalid scan, MotionUnavailable when motion does not cover the sweep
  /// (`out` is then left empty).
  void deskew(const PlanarScan& scan, const BeamTiming& timing, const mrpt::poses::CPose3D& mount,
              const MotionSource& motion, DeskewedScan& out);

  /// Corrects points grouped by firing time (3D clouds): `points` [m] in the laser frame, point i measured
  /// at the time of its firing. Writes corrected[i] for every point: a non-finite point stays
  /// non-finite. The reference time is the earliest / middle / latest firing; returns it [ns]. Each
  /// firing's affine map (KnotTrajectory::transformAt) is built once, for all its points. Throws
  /// InvalidInput("firings") when they do not give every point a firing or an offset is not finite, otherwise
  /// like deskew(); `corrected` is then left empty.
  TimeNs deskewFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings, TimeNs origin,
                       const mrpt::poses::CPose3D& mount, const MotionSource& motion,
                       std::vector<Eigen::Vector3d>& corrected);
  /// deskewFirings() in steps, for a caller that takes the corrected points a block at a time (no
  /// buffer of them all): beginFirings() checks the firings, builds their maps and returns the reference
  /// time [ns] (throws like deskewFirings()); then correctFiringBlock() writes the corrected positions of
  /// points [begin, end) to out[0, end - begin), the same numbers deskewFirings() writes (throws
  /// InvalidInput("firings") for a point's firing beyond the firings). `points`, `firings`, `mount` and
  /// `motion` must stay as they were, and alive, until the last block.
  TimeNs beginFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings, TimeNs origin,
                      const mrpt::poses::CPose3D& mount, const MotionSource& motion);
  void correctFiringBlock(const std::vector<Eigen::Vector3d>& points, const Firings& firings, std::size_t begin,
                          std::size_t end, Eigen::Vector3d* out) const;

  /// Corrects points with their own times (3D clouds): `points` [m] in the laser frame, each measured
  /// at origin + time_offsets[i] [s]. The reference time is the earliest / middle / latest of those.
  /// Non-finite points or offsets are skipped. Writes the corrected positions and their time offsets
  /// to the reference time (s) into `corrected` and `corrected_offsets`, and the index of each
  /// kept input point into `kept_indices`. Returns the reference time [ns]. Throws like deskew()
  /// (InvalidInput("time_offsets") for a size mismatch); the outputs are then left empty.
  TimeNs deskewPoints(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& time_offsets,
                      TimeNs origin, const mrpt::poses::CPose3D& mount, const MotionSource& motion,
                      std::vector<Eigen::Vector3d>& corrected, std::vector<double>& corrected_offsets,
                      std::vector<std::uint32_t>& kept_indices);

 private:
  void updateBeamDirections(const PlanarScan& scan);
  /// The motion to correct [begin, end] with: `motion` itself (linear), or twist_ fit to it.
  const MotionSource& motionFor(const MotionSource& motion, TimeNs begin, TimeNs end);
  // deskew() / deskewPoints() without the clean-up on failure
  void correctScan(const PlanarScan& scan, const BeamTiming& timing, const mrpt::poses::CPose3D& mount,
                   const MotionSource& motion, DeskewedScan& out);
  TimeNs correctFirings(const std::vector<Eigen::Vector3d>& points, const Firings& firings, TimeNs origin,
                        const mrpt::poses::CPose3D& mount, const MotionSource& motion,
                        std::vector<Eigen::Vector3d>& corrected);

  DeskewConfig config_;
  TwistMotion twist_;
  KnotTrajectory trajectory_;
  // unit beam directions of the last angle grid seen
  float grid_angle_min_ = 0.0f;
  float grid_angle_increment_ = 0.0f;
  std::vector<Eigen::Vector2d> beam_directions_;
  // deskewPoints(): the kept points and their firings
  std::vector<Eigen::Vector3d> kept_points_;
  Firings kept_firings_;
  // deskewFirings(): the affine map of each firing (exact mode: none; the chain's ends instead)
  struct FiringMap {
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation;
  };
  std::vector<FiringMap> firing_maps_;
  TimeNs firing_origin_ = 0;
  TimeNs firing_reference_ = 0;
  const mrpt::poses::CPose3D* firing_mount_ = nullptr;
  const MotionSource* firing_source_ = nullptr;
};

/// The exact chain for one point, composed with MRPT per call (exact mode, tests):
/// (mount^-1 (+) base(t_ref)^-1 (+) base(t) (+) mount) . raw.
Eigen::Vector3d deskewPointExact(const Eigen::Vector3d& raw, TimeNs point_time, TimeNs reference_time,
                                 const mrpt::poses::CPose3D& mount, const MotionSource& motion);

}  // namespace lidar_deskew::core
