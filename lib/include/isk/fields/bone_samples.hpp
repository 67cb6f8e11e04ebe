// HRBF samples of one bone's part (Vaillant et al. 2013, section 4.1):
// Poisson-disk samples of the part's surface, culled by the planes of
// eq. (2), plus closure points on the bone axis.
//
// - Poisson disk: candidates drawn uniformly by area on the part's triangles
//   (a fixed seed per joint: the same rig gives the same samples), kept in
//   turn when no kept sample lies closer than 0.75 * sqrt(area / target).
//   Normals are the geometric vertex normals interpolated across the
//   triangle, turned outward where the surface is wound inside out
//   (SurfaceOrientation).
// - Culling: samples whose position along the bone is not within
//   (h, 1 - h) are dropped (eq. 2; h = 0.05 by default), at the ends that
//   touch another part only: a free end (a fingertip, the end of a tube)
//   keeps the samples that close it.
// - Closure: at an end that touches another part, one point on the bone line
//   beyond the joint at distance s = distance from the joint to the part's
//   nearest vertex, normal along the bone, pointing outward.
//
// Samples are plain data: an application may add or remove points per bone
// before fitting (the paper's fix for shoulders).
#pragma once

#include <vector>

#include "isk/core/mesh.hpp"
#include "isk/core/surface_orientation.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/fields/hrbf.hpp"

namespace isk {

// At most this many times target_samples surface samples are kept per part:
// the Poisson-disk radius comes from the part's area, and a part whose area
// lies in long slivers (a vertex far off its part in a broken file) would
// keep up to 40 times the target; the fit's cost grows with the cube of the
// samples. The shared assets keep at most twice the target.
constexpr int kMaxSamplesPerTarget = 4;

// How a part is sampled (the paper's values by default).
struct BoneSamplingOptions {
  int target_samples = 50;     // Poisson-disk target per part
  double culling_h = 0.05;     // eq. (2), a fraction of the bone length
  bool closure_points = true;  // add closure points at touching ends
  unsigned seed = 0x15c0ffee;  // mixed with the joint index
  // Sample the skin only: the layers of a part (clothes around the skin,
  // isk/fields/bone_partition.hpp) are left out of its fit and follow the
  // skin's field. false: they are fitted with it.
  bool skin_only = true;
};

// The Hermite samples (model space, bind pose, unit outward normals) of
// one part.
struct BoneSamples {
  int joint = -1;          // the part's joint (skeleton index)
  HermiteSamples surface;  // Poisson-disk samples kept after culling
  HermiteSamples closure;  // 0, 1 or 2 closure points
  int culled = 0;          // surface samples dropped by eq. (2)

  // surface followed by closure: what the fit uses.
  HermiteSamples all() const;
};

// Samples the part of `joint` (a skeleton index) of `mesh` (the rig's rest
// mesh, as partitioned by `partition`). `orientation`: the mesh's outward
// side (SurfaceOrientation::of(mesh)); null takes the winding as it is. An
// empty part gives no samples. Deterministic for a given seed; does not
// throw for valid inputs.
BoneSamples sampleBonePart(const Mesh& mesh, const BonePartition& partition,
                           int joint, const BoneSamplingOptions& options = {},
                           const SurfaceOrientation* orientation = nullptr);

}  // namespace isk
