// Animation clips: per-joint keyframe channels, sampled at any time.
//
// Sampling interpolates translations and scales linearly and rotations with
// spherical linear interpolation; before the first key and after the last the
// end keys hold. A joint without a channel keeps its rest local transform.
#pragma once

#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"
#include "isk/rig/skeleton.hpp"

namespace isk {

// The keys of one joint's local transform (relative to its parent, model
// units). Each of the three tracks may be empty: that part then keeps the
// joint's rest local value.
struct JointChannel {
  int joint = -1;                             // skeleton index
  std::vector<double> translation_times;      // seconds, increasing
  std::vector<Eigen::Vector3f> translations;  // one per time
  std::vector<double> rotation_times;         // seconds, increasing
  std::vector<Eigen::Quaternionf> rotations;  // unit, one per time
  std::vector<double> scale_times;            // seconds, increasing
  std::vector<Eigen::Vector3f> scales;        // one per time
};

// A named animation of a skeleton's joints.
struct AnimationClip {
  std::string name;
  double start = 0.0;     // seconds, time of the first key
  double duration = 0.0;  // seconds
  std::vector<JointChannel> channels;

  // Local transforms of every joint (#joints of `skeleton`) at time t
  // (seconds, clamped to [start, start + duration]). Does not validate:
  // channels must name joints of `skeleton` (validate()).
  TransformList sampleLocal(const Skeleton& skeleton, double t) const;

  // Checks joint indices, sorted finite times and finite keys; names the
  // first bad channel.
  Validation validate(const Skeleton& skeleton) const;
};

// A procedural clip bending every joint about an axis perpendicular to its
// bone, from 0 to `max_angle_radians` over `duration` seconds. Used when an
// asset has no clip and by the procedural rigs. The clip starts at 0 s; at
// t = 0 every joint is at its rest local transform (the bind pose).
AnimationClip makeBendClip(const Skeleton& skeleton, float max_angle_radians,
                           double duration = 1.0);

}  // namespace isk
