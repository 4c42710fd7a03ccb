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

/// (rotation, translation) = (a_rotation, a_translation) (+) (rotation, translation), bit for bit as MRPT's
/// CPose3D::composeFrom computes it: each coordinate a_t + a_R(r, 0) b_t + ... left to right, each
/// rotation entry a_R(r, 0) b_R(0, c) + (a_R(r, 1) b_R(1, c) + a_R(r, 2) b_R(2, c)) (its Eigen product
/// of row-major matrices; Eigen's of column-major ones rounds differently).
inline void composeInPlace(const Eigen::Matrix3d& a_rotation, const Eigen::Vector3d& a_translation,
                           Eigen::Matrix3d& rotation, Eigen::Vector3d& translation) {
  const Eigen::Vector3d b = translation;
  for (int r = 0; r < 3; ++r)
    translation[r] = a_translation[r] + a_rotation(r, 0) * b[0] + a_rotation(r, 1) * b[1] + a_rotation(r, 2) * b[2];
  const Eigen::Matrix3d b_rotation = rotation;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      rotation(r, c) = a_rotation(r, 0) * b_rotation(0, c) +
                       (a_rotation(r, 1) * b_rotation(1, c) + a_rotation(r, 2) * b_rotation(2, c));
  }
}

}  // namespace lidar_deskew::core::detail
