#include "isk/rig/pose.hpp"

namespace isk {

TransformList globalTransforms(const Skeleton& skeleton,
                               const TransformList& locals) {
  TransformList globals(skeleton.joints.size());
  for (size_t j = 0; j < globals.size(); ++j) {
    const int parent = skeleton.joints[j].parent;
    globals[j] =
        (parent < 0 ? skeleton.root_parent : globals[parent]) * locals[j];
  }
  return globals;
}

TransformList skinningTransforms(const Skeleton& skeleton,
                                 const TransformList& globals) {
  TransformList skinning(skeleton.joints.size());
  for (size_t j = 0; j < skinning.size(); ++j) {
    skinning[j] = globals[j] * skeleton.joints[j].inverse_bind;
  }
  return skinning;
}

TransformList bindPoseSkinning(const Skeleton& skeleton) {
  return TransformList(skeleton.joints.size(), Eigen::Affine3f::Identity());
}

}  // namespace isk
