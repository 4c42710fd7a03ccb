// The PCL point type of the corrected cloud: x y z intensity t index.
#pragma once

#define PCL_NO_PRECOMPILE
#include <pcl/point_types.h>
#include <pcl/register_point_struct.h>

#include <cstdint>

namespace lidar_deskew {

/// A corrected return. x, y, z [m] in the laser frame at the reference time; intensity as the input
/// (0 when it had none); t [s] = beam time - reference time; index = the beam's index in the input.
struct EIGEN_ALIGN16 PointXYZITI {
  PCL_ADD_POINT4D;
  float intensity;
  float t;
  std::uint32_t index;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

}  // namespace lidar_deskew

POINT_CLOUD_REGISTER_POINT_STRUCT(lidar_deskew::PointXYZITI,
                                  (float, x, x)(float, y, y)(float, z, z)(float, intensity, intensity)(
                                      float, t, t)(std::uint32_t, index, index))
