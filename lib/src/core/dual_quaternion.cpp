#include "isk/core/dual_quaternion.hpp"

#include <Eigen/SVD>

namespace isk {

DualQuaternion DualQuaternion::fromTransform(const Eigen::Affine3f& transform) {
  // Polar decomposition: the closest rotation to the linear part.
  Eigen::JacobiSVD<Eigen::Matrix3f> svd(
      transform.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3f rotation = svd.matrixU() * svd.matrixV().transpose();
  if (rotation.determinant() < 0.f) {
    Eigen::Matrix3f u = svd.matrixU();
    u.col(2) = -u.col(2);
    rotation = u * svd.matrixV().transpose();
  }
  DualQuaternion dq;
  dq.real = Eigen::Quaternionf(rotation).normalized();
  const Eigen::Vector3f t = transform.translation();
  // dual = 0.5 * (0, t) * real
  const Eigen::Quaternionf tq(0.f, t.x(), t.y(), t.z());
  dq.dual.coeffs() = 0.5f * (tq * dq.real).coeffs();
  return dq;
}

Eigen::Vector3f DualQuaternion::translation() const {
  // t = 2 * dual * conj(real)
  const Eigen::Quaternionf t = dual * real.conjugate();
  return 2.f * t.vec();
}

Eigen::Vector3f DualQuaternion::transformPoint(const Eigen::Vector3f& p) const {
  return rotateVector(p) + translation();
}

Eigen::Vector3f DualQuaternion::rotateVector(const Eigen::Vector3f& v) const {
  return real * v;
}

void packDualQuaternion(const DualQuaternion& dq, float out[8]) {
  out[0] = dq.real.x();
  out[1] = dq.real.y();
  out[2] = dq.real.z();
  out[3] = dq.real.w();
  out[4] = dq.dual.x();
  out[5] = dq.dual.y();
  out[6] = dq.dual.z();
  out[7] = dq.dual.w();
}

}  // namespace isk
