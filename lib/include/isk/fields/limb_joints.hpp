// The joints of a character's mirrored limbs, where the paper composes with
// the gradient-based blend (Vaillant et al. 2013, section 4.2: "elbows,
// shoulders and knees" blend, the union elsewhere), found from the rig.
//
// The field tree: each joint whose bone has a field hangs under its nearest
// ancestor that has one (the pairs of isk/fields/field_composition.hpp). Two
// siblings of that tree are mirrored limbs when they are the only two of
// their siblings whose subtrees have the same shape (the same branching, the
// order of children aside) and whose subtrees' bone lengths (bind pose) sum
// to within kLimbLengthTolerance of each other: arms, legs, a pair of ears
// or horns, but not five fingers nor a tail beside a spine. The limb joints
// are the joints along each such limb from its root down to its first
// branch (the root excluded: it meets the body, which it does not mirror):
// a human's shoulder, elbow and wrist, knee, ankle and ball; a quadruped's
// every leg joint; not the fingers past the hand.
#pragma once

#include <vector>

#include "isk/rig/skeleton.hpp"

namespace isk {

// Largest difference of two mirrored limbs' summed bone lengths, as a
// fraction of the longer.
constexpr double kLimbLengthTolerance = 0.15;

// The limb joints (ascending joint indices) of `skeleton`, whose joint j has
// a field where field_of_joint[j] >= 0 (#joints).
std::vector<int> limbJoints(const Skeleton& skeleton,
                            const std::vector<int>& field_of_joint);

}  // namespace isk
