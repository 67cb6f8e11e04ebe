#include "isk/rig/skeleton.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <string>

namespace isk {

int Skeleton::skinJointCount() const {
  int count = 0;
  for (const Joint& joint : joints) count += joint.is_skin_joint ? 1 : 0;
  return count;
}

int Skeleton::find(const std::string& name) const {
  for (int j = 0; j < jointCount(); ++j) {
    if (joints[j].name == name) return j;
  }
  return -1;
}

TransformList Skeleton::bindGlobals() const {
  TransformList globals(joints.size());
  for (size_t j = 0; j < joints.size(); ++j) {
    globals[j] = joints[j].inverse_bind.inverse(Eigen::Affine);
  }
  return globals;
}

Validation Skeleton::validate() const {
  if (joints.empty()) return Validation::fail("the skeleton has no joint");
  if (!root_parent.matrix().allFinite()) {
    return Validation::fail("the transform above the skeleton is not finite");
  }
  for (int j = 0; j < jointCount(); ++j) {
    const Joint& joint = joints[j];
    const std::string where =
        "joint '" + joint.name + "' (" + std::to_string(j) + ")";
    if (joint.parent >= j || joint.parent < -1) {
      return Validation::fail(where + " has parent " +
                              std::to_string(joint.parent) +
                              ": parents must precede children");
    }
    if (!joint.rest_local.matrix().allFinite() ||
        !joint.inverse_bind.matrix().allFinite()) {
      return Validation::fail(where + " has a non-finite transform");
    }
    // Singular values of the bind linear part: equal (uniform scale) for a
    // rigid frame up to a unit conversion; anything else is scale or shear.
    const Eigen::Vector3f sigma =
        Eigen::JacobiSVD<Eigen::Matrix3f>(joint.inverse_bind.linear())
            .singularValues();
    if (!(sigma(2) > 0.f)) {
      return Validation::fail(where + " has a singular inverse bind matrix");
    }
    if ((sigma(0) - sigma(2)) > 1e-3f * sigma(0)) {
      return Validation::fail(where +
                              " has a non-rigid bind transform (scale or shear "
                              "with singular values " +
                              std::to_string(sigma(0)) + ", " +
                              std::to_string(sigma(1)) + ", " +
                              std::to_string(sigma(2)) + ")");
    }
    if (joint.inverse_bind.linear().determinant() < 0.f) {
      return Validation::fail(where + " has a mirrored bind transform");
    }
  }
  return Validation::ok();
}

}  // namespace isk
