// Unit dual quaternions for rigid transforms (Kavan et al. 2008).
#pragma once

#include "isk/core/types.hpp"

namespace isk {

// q = real + eps * dual: rotation `real` (unit), then translation t.
struct DualQuaternion {
  Eigen::Quaternionf real = Eigen::Quaternionf::Identity();  // rotation
  Eigen::Quaternionf dual = Eigen::Quaternionf(0, 0, 0, 0);  // 0.5 * t * real

  // The rigid part of `transform`: rotation from a polar decomposition of its
  // linear part (any scale or shear is dropped), translation as is.
  static DualQuaternion fromTransform(const Eigen::Affine3f& transform);

  // t = 2 * dual * conj(real).
  Eigen::Vector3f translation() const;
  // R p + t (expects a unit real part).
  Eigen::Vector3f transformPoint(const Eigen::Vector3f& p) const;
  // R v, no translation (directions, normals).
  Eigen::Vector3f rotateVector(const Eigen::Vector3f& v) const;
};

// The 8 floats the kernels take per joint: real (x, y, z, w), dual (x, y, z,
// w).
void packDualQuaternion(const DualQuaternion& dq, float out[8]);

}  // namespace isk
