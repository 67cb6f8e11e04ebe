// Joint hierarchy with bind pose.
//
// Model space is the scene's world space at the bind pose: the space of
// Mesh::positions. Each joint has a local transform relative to its parent
// (the node transform in the file, used where an animation has no channel) and
// an inverse bind matrix taking model space to the joint's space at the bind
// pose. Skinning transforms are `global(pose) * inverse_bind`, so the bind pose
// gives identity and reproduces the input mesh.
#pragma once

#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"

namespace isk {

// One joint (a node of the file's hierarchy).
struct Joint {
  std::string name;              // the node name in the file; may be empty
  int parent = -1;               // index of the parent joint, -1 for roots
  Eigen::Affine3f rest_local;    // local to parent (or to root_parent)
  Eigen::Affine3f inverse_bind;  // model space -> joint space at bind pose
  bool is_skin_joint = false;    // referenced by the skin weights of the file
};

// The joints of a rig, with their hierarchy and bind pose.
struct Skeleton {
  std::vector<Joint> joints;  // parents precede children
  // Transform of the scene above the skeleton's roots (fixed, not animated).
  Eigen::Affine3f root_parent = Eigen::Affine3f::Identity();

  int jointCount() const { return static_cast<int>(joints.size()); }
  // Joints with is_skin_joint set.
  int skinJointCount() const;
  // Index of the joint named `name` (the first, if several), -1 if none.
  int find(const std::string& name) const;

  // Bind pose global transforms (inverse of inverse_bind), #joints.
  TransformList bindGlobals() const;

  // Checks parent order, finiteness, and that every bind transform is rigid
  // up to one uniform scale per joint (a unit conversion: it stays in
  // inverse_bind and cancels against the same scale in the posed globals);
  // names the first bad joint.
  Validation validate() const;
};

}  // namespace isk
