#include "lidar_deskew/ros/scan_processor.h"

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <iterator>
#include <utility>

#include <pcl_conversions/pcl_conversions.h>

#include "lidar_deskew/ros/conversions.h"
#include "../core/simd.h"  // (SSE2 intrinsics too)

// toCloud()'s points by AVX2 where the CPU has it (where the core builds AVX2 clones: GCC on x86-64), by
// generic vectors with __builtin_shufflevector (GCC 12 on).
#if defined(LIDAR_DESKEW_HAS_AVX2_CLONES) && LIDAR_DESKEW_VECTOR_SHUFFLES
#define LIDAR_DESKEW_CLOUD_AVX2 1
#endif

namespace lidar_deskew::ros_adapter {
namespace {

/// The base stands still: correcting with it is the plain polar projection.
class StandingStill final : public core::MotionSource {
 public:
  mrpt::poses::CPose3D basePose(core::TimeNs /*time*/) const override { return {}; }
};

/// The outputs' stamp: the reference time on whole microseconds, since a PCL cloud's stamp holds no
/// more (pcl_conversions truncates it), so that both outputs of one scan carry the same stamp.
core::TimeNs outputStamp(core::TimeNs reference_time) {
  return reference_time / 1000 * 1000;
}

static_assert(sizeof(PointXYZITI) == 32 && offsetof(PointXYZITI, intensity) == 16 &&
                  offsetof(PointXYZITI, t) == 20 && offsetof(PointXYZITI, index) == 24,
              "toCloud() writes a point as two 16-byte halves");

/// Corrected points read as cloud points, so that the cloud's vector is built from them in one pass
/// (assign(): one allocation, each point constructed in place, no zeroing before). kVectors: by generic
/// vectors, for code built for AVX2 (see operator*); else by SSE2 intrinsics.
template <bool kVectors>
class CloudPointReader {
 public:
  using iterator_category = std::random_access_iterator_tag;
  using value_type = PointXYZITI;
  using difference_type = std::ptrdiff_t;
  using pointer = const PointXYZITI*;
  using reference = PointXYZITI;

  CloudPointReader(const core::DeskewedPoint* point, double t_offset) : point_(point), t_offset_(t_offset) {}

  /// Every byte defined, the padding too (data[3] and the 4 bytes after index are serialised as they
  /// are): the same scan gives the same message bytes, run after run.
  PointXYZITI operator*() const {
    PointXYZITI out;
#if defined(LIDAR_DESKEW_CLOUD_AVX2)
    if constexpr (kVectors) {
      // Built for AVX2: x y z and time_offset + t_offset (the sum in the t lane only, so that x y z keep
      // their bits, -0 included) become floats by one 4-lane conversion, which rounds as a cast does.
      using Double4 = double __attribute__((vector_size(32)));
      using Float4 = float __attribute__((vector_size(16)));
      using Bits2 = std::uint64_t __attribute__((vector_size(16)));
      Double4 xyzt;  // time_offset follows z
      std::memcpy(&xyzt, point_->position.data(), sizeof xyzt);
      const Float4 xyzt_float =
          __builtin_convertvector(__builtin_shufflevector(xyzt, xyzt + t_offset_, 0, 1, 2, 7), Float4);
      std::uint64_t intensity_index_bits;
      std::memcpy(&intensity_index_bits, &point_->intensity, sizeof intensity_index_bits);
      const Float4 intensity_index = reinterpret_cast<Float4>(Bits2{intensity_index_bits, 0});
      const Float4 first = __builtin_shufflevector(xyzt_float, Float4{}, 0, 1, 2, 4);  // x y z 0
      const Float4 second =
          __builtin_shufflevector(intensity_index, xyzt_float, 0, 7, 1, 2);  // intensity t index 0
      std::memcpy(static_cast<void*>(&out), &first, sizeof first);
      std::memcpy(reinterpret_cast<char*>(&out) + sizeof first, &second, sizeof second);
      return out;
    }
#endif
    const float t = static_cast<float>(point_->time_offset + t_offset_);
#if defined(__SSE2__)
    // Each half of the point as one 16-byte value (SSE2 is part of x86-64); cvtpd2ps rounds as a cast does.
    const __m128 xy = _mm_cvtpd_ps(_mm_loadu_pd(point_->position.data()));
    const __m128 z = _mm_cvtsd_ss(_mm_setzero_ps(), _mm_load_sd(point_->position.data() + 2));
    _mm_store_ps(out.data, _mm_movelh_ps(xy, z));
    std::int32_t intensity_bits, t_bits;
    std::memcpy(&intensity_bits, &point_->intensity, sizeof intensity_bits);
    std::memcpy(&t_bits, &t, sizeof t_bits);
    _mm_store_si128(reinterpret_cast<__m128i*>(&out.intensity),
                    _mm_setr_epi32(intensity_bits, t_bits, static_cast<std::int32_t>(point_->beam_index), 0));
#else
    std::memset(static_cast<void*>(&out), 0, sizeof out);
    out.x = static_cast<float>(point_->position.x());
    out.y = static_cast<float>(point_->position.y());
    out.z = static_cast<float>(point_->position.z());
    out.intensity = point_->intensity;
    out.t = t;
    out.index = point_->beam_index;
#endif
    return out;
  }
  CloudPointReader& operator++() {
    ++point_;
    return *this;
  }
  CloudPointReader operator++(int) {
    CloudPointReader before = *this;
    ++point_;
    return before;
  }
  CloudPointReader& operator--() {
    --point_;
    return *this;
  }
  CloudPointReader& operator+=(difference_type n) {
    point_ += n;
    return *this;
  }
  difference_type operator-(const CloudPointReader& other) const { return point_ - other.point_; }
  bool operator==(const CloudPointReader& other) const { return point_ == other.point_; }
  bool operator!=(const CloudPointReader& other) const { return point_ != other.point_; }

 private:
  const core::DeskewedPoint* point_;
  double t_offset_;
};

template <bool kVectors>
void assignCloudPoints(const core::DeskewedPoint* points, std::size_t count, double t_offset,
                       DeskewedCloud& cloud) {
  cloud.points.assign(CloudPointReader<kVectors>(points, t_offset),
                      CloudPointReader<kVectors>(points + count, t_offset));
}

#if defined(LIDAR_DESKEW_CLOUD_AVX2)
static_assert(
    sizeof(core::DeskewedPoint) == 40 && sizeof(Eigen::Vector3d) == 24,
    "CloudPointReader<true> reads x y z time_offset as 4 doubles, intensity and beam_index as 8 bytes");

/// assignCloudPoints() built for AVX2, everything it calls inlined (flatten): 13 instructions a point
/// instead of 19.
[[gnu::target("avx2"), gnu::flatten]] void assignCloudPointsAvx2(const core::DeskewedPoint* points,
                                                                 std::size_t count, double t_offset,
                                                                 DeskewedCloud& cloud) {
  assignCloudPoints<true>(points, count, t_offset, cloud);
}
#endif

/// `t_offset` [s] = reference time - the header's stamp, added to every point's t so that t stays
/// relative to the stamp (under a microsecond).
boost::shared_ptr<DeskewedCloud> toCloud(const core::DeskewedScan& corrected, const std_msgs::Header& header,
                                         double t_offset) {
  auto cloud = boost::make_shared<DeskewedCloud>();
  pcl_conversions::toPCL(header, cloud->header);
  const core::DeskewedPoint* const points = corrected.points.data();
#if defined(LIDAR_DESKEW_CLOUD_AVX2)
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2) {
    assignCloudPointsAvx2(points, corrected.points.size(), t_offset, *cloud);
  } else
#endif
  {
    assignCloudPoints<false>(points, corrected.points.size(), t_offset, *cloud);
  }
  // At least one slot: pcl_ros serializes with memcpy from points.data(), which must not be null even
  // for an empty cloud (undefined behaviour found by fuzz_messages).
  cloud->points.reserve(1);
  cloud->width = static_cast<std::uint32_t>(cloud->points.size());
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

}  // namespace

const char* PreparedScan::timingFallback() const {
  switch (timing.source) {
    case core::TimingSource::kTimeIncrement:
      return nullptr;
    case core::TimingSource::kScanTime:
      return "scans have time_increment = 0; beam times come from scan_time";
    default:
      return "scans have time_increment = 0; beam times come from the scan_period parameter";
  }
}

void checkTfGaps(double max_tf_gap, const core::MotionSource& motion, core::TimeNs first, core::TimeNs last) {
  if (max_tf_gap <= 0.0)
    return;
  const core::TimeNs gap = motion.longestGap(first, last);
  if (gap > core::secondsToNs(max_tf_gap)) {
    throw TfGapTooLong(first, "tf has a gap of " + std::to_string(gap * 1e-9) +
                                  " s within the sweep (more than max_tf_gap " + std::to_string(max_tf_gap) +
                                  " s)");
  }
}

ScanProcessor::ScanProcessor(const DeskewParams& params)
    : params_(params), deskewer_(params.deskew), rebinner_(params.rebin) {}

PreparedScan ScanProcessor::prepare(const sensor_msgs::LaserScan::ConstPtr& message) const {
  PreparedScan prepared;
  prepared.message = message;
  if (message->header.frame_id.empty())
    throw core::InvalidInput("header.frame_id", "is empty");
  prepared.scan = fromMsg(*message);
  core::validateScan(prepared.scan);
  prepared.timing = core::resolveTiming(prepared.scan, params_.timing);
  // ros::Time holds [0, 2^32) s; keep a margin for lookups and waiting beyond the sweep.
  constexpr core::TimeNs kLatestTime = (static_cast<core::TimeNs>(1) << 32) * 1'000'000'000 - 100'000'000'000;
  if (prepared.timing.earliestBeamTime() < 0 || prepared.timing.latestBeamTime() > kLatestTime) {
    throw core::InvalidInput("header.stamp", "puts the sweep outside the range of ROS time");
  }
  return prepared;
}

DeskewedOutputs ScanProcessor::correct(const PreparedScan& prepared, const mrpt::poses::CPose3D& mount,
                                       const core::MotionSource& motion) {
  checkTfGaps(params_.max_tf_gap, motion, prepared.timing.earliestBeamTime(),
              prepared.timing.latestBeamTime());
  deskewer_.deskew(prepared.scan, prepared.timing, mount, motion, corrected_);
  const core::PlanarScan& planar = prepared.scan;
  rebinner_.rebin(corrected_, {planar.angle_min, planar.angle_increment, planar.ranges.size()},
                  core::noReturnValue(planar, corrected_), rebinned_);

  const sensor_msgs::LaserScan& input = *prepared.message;
  std_msgs::Header header = input.header;
  const core::TimeNs stamp = outputStamp(corrected_.reference_time);
  header.stamp = toRosTime(stamp);
  DeskewedOutputs outputs;
  const auto corrected_scan = boost::make_shared<sensor_msgs::LaserScan>();
  sensor_msgs::LaserScan& scan = *corrected_scan;
  scan.header = header;
  scan.angle_min = input.angle_min;
  scan.angle_max = input.angle_max;
  scan.angle_increment = input.angle_increment;
  scan.time_increment = 0.0f;  // every beam now refers to the reference time
  scan.scan_time = input.scan_time;
  scan.range_min = input.range_min;
  scan.range_max = input.range_max;
  // Moved, not copied: the message keeps the re-binner's vectors (the next scan's are allocated anew).
  scan.ranges = std::move(rebinned_.ranges);
  scan.intensities = std::move(rebinned_.intensities);
  outputs.scan = corrected_scan;
  outputs.cloud = toCloud(corrected_, header, core::nsToSeconds(corrected_.reference_time - stamp));
  return outputs;
}

DeskewedOutputs ScanProcessor::passThrough(const PreparedScan& prepared) {
  deskewer_.deskew(prepared.scan, prepared.timing, mrpt::poses::CPose3D(), StandingStill(), corrected_);
  DeskewedOutputs outputs;
  outputs.scan = prepared.message;  // republished as is
  std_msgs::Header header = prepared.message->header;
  const core::TimeNs stamp = outputStamp(corrected_.reference_time);
  header.stamp = toRosTime(stamp);  // the cloud's t is relative to it
  outputs.cloud = toCloud(corrected_, header, core::nsToSeconds(corrected_.reference_time - stamp));
  return outputs;
}

}  // namespace lidar_deskew::ros_adapter
