// Midpoint (1-to-4) subdivision of a rig, for large benchmark models.
//
// Every edge gets a vertex at its midpoint whose skin weights are the average
// of its ends' (then renormalized), every triangle is split in four. Vertices
// at the same position along a seam share their edge midpoints only when they
// share the edge's vertex indices, so seams stay split like the input.
#pragma once

#include "isk/rig/rig.hpp"

namespace isk {

// Applies `levels` rounds of 1-to-4 subdivision (vertex count grows about 4x
// per level). Clips and skeleton are kept. Throws isk::Error(kInvalidArgument)
// for `levels` outside 0..6.
Rig subdivideRig(const Rig& rig, int levels);

}  // namespace isk
