// A skinned character: mesh, skeleton, weights and clips, as loaded or built.
#pragma once

#include <string>
#include <vector>

#include "isk/core/mesh.hpp"
#include "isk/core/validation.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/skeleton.hpp"
#include "isk/rig/skin_weights.hpp"

namespace isk {

// Everything skinning needs, in model space (see skeleton.hpp); built by
// importRig (isk/io/import.hpp) or the procedural builders
// (isk/tools/procedural.hpp), or filled by the application (then validate()).
struct Rig {
  std::string source;                // file path or "builtin:NAME"
  Mesh mesh;                         // the bind-pose skin, #V vertices
  Skeleton skeleton;                 // #joints joints
  SkinWeights weights;               // #V rows of joint indices and weights
  std::vector<AnimationClip> clips;  // may be empty
  // Things fixed or ignored while loading (weights normalized, meshes
  // skipped...), one sentence each.
  std::vector<std::string> warnings;

  // Validates every part and their agreement (weight rows = vertices, joint
  // indices in range); the reason names the vertex, joint or clip.
  Validation validate() const;

  // Index of the clip named `name`, -1 if none.
  int findClip(const std::string& name) const;

  // Diagonal of the mesh's axis-aligned bounding box (0 for an empty mesh),
  // model units.
  float boundingBoxDiagonal() const;
};

}  // namespace isk
