// Procedural rigs for tests, benchmarks and the demo (no file needed).
#pragma once

#include <string>
#include <vector>

#include "isk/rig/rig.hpp"

namespace isk {

// Shape of makeCylinderRig's cylinder; lengths in model units.
struct CylinderRigOptions {
  int bones = 2;       // 1 to 64 bones along +x, equal lengths
  float radius = 1.f;  // model units
  float length = 8.f;  // whole cylinder
  int rings = 64;      // vertex rings along the length
  int segments = 48;   // vertices around each ring
  float taper = 0.f;   // tip radius = radius * (1 - taper)
  // Width of the weight blend around each inner joint, in bone lengths.
  float blend_width = 0.25f;
};

// A closed, manifold cylinder along +x from the origin, capped at both ends,
// with `bones` joints chained along the axis (finger-like), smooth weights
// around the inner joints and a bend clip ("bend") of every joint to 90
// degrees. Throws isk::Error(kInvalidArgument) for options out of range
// (bones 1..64, positive radius and length, rings >= 2, segments >= 3, taper
// in [0, 1), blend_width in (0, 0.5]).
Rig makeCylinderRig(const CylinderRigOptions& options = {});

// A simple arm: upper arm, forearm and a flattened hand on a 4-joint chain
// (shoulder, elbow, wrist, hand tip), tapered and closed, with a bend clip.
// About 10 model units long along +x; `rings_per_unit` vertex rings per
// model unit (>= 1), `segments` vertices per ring (>= 3), else
// isk::Error(kInvalidArgument).
Rig makeArmRig(int rings_per_unit = 12, int segments = 40);

// The arm above dressed in a sleeve: a closed shell (another mesh part,
// "sleeve", 1.05 to 1.12 times the arm's radii) from the shoulder past the
// elbow to the middle of the forearm, weighted as the skin under it -- two
// layers sharing bones, as clothes over a body. Coarser by default (8 rings
// per unit, 32 segments). Same argument checks as makeArmRig.
Rig makeSleevedArmRig(int rings_per_unit = 8, int segments = 32);

// A leg: thigh, calf and a flattened foot on a 4-joint chain (hip, knee,
// ankle, toe tip), about 10 model units along +x, thicker than the arm --
// for knee bends to 150 degrees and beyond, where the calf presses on the
// thigh. Same argument checks as makeArmRig.
Rig makeLegRig(int rings_per_unit = 8, int segments = 40);

// The names accepted by makeBuiltinRig ("cylinder", "finger", "arm",
// "sleeved-arm", "leg").
std::vector<std::string> builtinRigNames();

// Builds a named procedural rig: "cylinder" (2 bones, radius 1, length 8),
// "finger" (3 tapered phalanges), "arm", "sleeved-arm" or "leg". Throws
// isk::Error (kInvalidArgument) listing the valid names for any other name.
Rig makeBuiltinRig(const std::string& name);

}  // namespace isk
