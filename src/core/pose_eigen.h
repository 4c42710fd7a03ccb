// Private helpers: MRPT poses <-> Eigen rotation / translation, and the cross-product matrix.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <Eigen/Core>

namespace lidar_deskew::core::detail {

inline Eigen::Matrix3d rotationOf(const mrpt::poses::CPose3D& pose) {
  return pose.getRotationMatrix().asEigen();
}

inline Eigen::Vector3d translationOf(const mrpt::poses::CPose3D& pose) {
  return Eigen::Vector3d(pose.x(), pose.y(), pose.z());
}

/// The cross-product matrix of v: skew(v) w = v x w.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d k;
  k << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return k;
}

inline mrpt::poses::CPose3D poseOf(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation) {
  mrpt::math::CMatrixDouble33 rotation_matrix(rotation);
  mrpt::math::CVectorFixedDouble<3> xyz;
  for (int axis = 0; axis < 3; ++axis)
    xyz[axis] = translation[axis];
  return mrpt::poses::CPose3D::FromRotationAndTranslation(rotation_matrix, xyz);
}

}  // namespace lidar_deskew::core::detail
