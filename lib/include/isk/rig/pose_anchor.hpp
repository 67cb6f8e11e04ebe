// Where a pose stands, taken out of a frame's arithmetic: a skinner
// subtracts the anchor from every skinning transform's translation, skins
// and tracks about the origin, and adds the anchor back to the results.
// Without it, a character far from the origin (tens of metres out, as in a
// game level) is skinned in float coordinates whose rounding the tracking
// amplifies where skin meets skin, and its deformation changes as it walks.
//
// The anchor is zero while the pose stays within kAnchorFreeSteps steps (a
// step: the power of two at least the rest bounding box diagonal) of the
// origin on every axis: there the frame is computed as given, bit for bit
// (rigid and untracked parts exactly on skinning), with coordinates at most
// a few diagonals large. Beyond, it is rounded to whole steps, so that a
// pose moved by whole steps (exactly, in float) gets the same anchored pose,
// so the same frame, moved (up to the rounding of the final addition).
#pragma once

#include <vector>

#include "isk/core/types.hpp"

namespace isk {

// How far (in anchor steps, per axis) a pose may stand from the origin and
// still be computed in its given coordinates.
constexpr float kAnchorFreeSteps = 2.f;

// The anchor step of a character of this rest diagonal: the smallest power
// of two not below it (1 for a non-positive or non-finite diagonal).
float anchorStep(float rest_diagonal);

// The anchor of a pose (#joints skinning transforms): the mean over the
// joints of where each one's transform carries rest_centers[j] (#joints: the
// rest bounding box centre of the joint's character), rounded per axis to a
// whole multiple of `step`. Zero when that mean is within kAnchorFreeSteps
// steps of the origin on every axis, for an empty pose, a pose whose mean is
// not finite (the skinner's own checks then name the bad transform) or sizes
// that do not match. Never throws.
Eigen::Vector3f poseAnchor(const TransformList& skinning,
                           const std::vector<Eigen::Vector3f>& rest_centers,
                           float step);

// The rest centres of a character's `joints` joints: the bounding box
// centre of its rest positions (#V by 3), once per joint (zero for no
// vertices).
std::vector<Eigen::Vector3f> restCenters(const Matrix3Xf& rest_positions,
                                         int joints);

// `skinning` with `anchor` taken out of every translation (in place).
void subtractAnchor(const Eigen::Vector3f& anchor, TransformList& skinning);

}  // namespace isk
