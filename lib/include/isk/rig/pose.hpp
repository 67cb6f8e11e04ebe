// From local joint transforms to the skinning transforms the kernels use.
#pragma once

#include "isk/core/types.hpp"
#include "isk/rig/skeleton.hpp"

namespace isk {

// Model-space global transforms, #joints (root_parent * ... * local), from
// `locals` (#joints local transforms, e.g. AnimationClip::sampleLocal).
// Sizes are not checked: `locals` must hold #joints entries. Never throws.
TransformList globalTransforms(const Skeleton& skeleton,
                               const TransformList& locals);

// Skinning transforms global * inverse_bind, #joints: model space (bind
// pose) to model space (posed). Identity everywhere at the bind pose.
// `globals` must hold #joints entries (not checked). What run() of every
// skinner takes.
TransformList skinningTransforms(const Skeleton& skeleton,
                                 const TransformList& globals);

// The bind pose: #joints identity skinning transforms.
TransformList bindPoseSkinning(const Skeleton& skeleton);

}  // namespace isk
