// One bone's compactly supported field (Vaillant et al. 2013, section 4.1),
// analytic form:
//
//   f_i(x) = t_r(max(d_i(x), rho(x) - R))
//
// d_i is the HRBF fitted to the bone's samples; r is the distance from the
// bone segment to the farthest sample used in the fit, so f_i = 1 is reached
// only near the skeleton; rho is the distance from x to the bone segment and
// R >= r the distance from the segment to the farthest sample or vertex of
// the part.
//
// The max with rho - R is our guard, not the paper's: the cubic HRBF keeps
// growing away from its samples and on an open or flat part it turns
// negative again far away, so t_r(d_i) alone is not compactly supported
// (it reaches 1 on whole half-spaces). On the part's surface the guard
// changes nothing (there d_i is about 0 and rho - R <= 0), and inside a
// closed part rarely (d_i < rho - R means a point deeper inside than its
// distance to the R-capsule); beyond R + r from the bone it makes f_i
// exactly 0. So the support lies in the capsule of radius R + r around the
// bone, and `support_box`, that capsule's box in the bone frame, loses
// nothing.
//
// The field lives in the bone's frame: origin at b0, x along the bone (for a
// point bone, the model axes).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/fields/bone_samples.hpp"
#include "isk/fields/hrbf.hpp"

namespace isk {

// The analytic field of one bone, as fitted by fitBoneField. Lengths are in
// model units (those of the rig's mesh); values lie in [0, 1], 0.5 on the
// part's surface, larger inside.
struct BoneField {
  int joint = -1;           // the joint (skeleton index) of the part
  Hrbf hrbf;                // fitted in model space (bind pose)
  double radius = 0;        // r of t_r, model units
  double guard_radius = 0;  // R of the guard (above), model units
  BoneSegment segment;      // b0 -> b1, bind pose, model space
  // Bone frame (origin b0, x along the bone) to model space, bind pose.
  Eigen::Isometry3d bone_to_model = Eigen::Isometry3d::Identity();
  // Where f can be non-zero: the box of the capsule of radius R + r around
  // the bone, in the bone frame.
  Eigen::AlignedBox3d support_box;

  // max(d_i, rho - R) and its gradient (model space) at model-space x: a
  // signed distance, model units, negative inside.
  void guardedDistance(const Eigen::Vector3d& x, double& distance,
                       Eigen::Vector3d& gradient) const;
  // The same from an HRBF value and gradient already evaluated at x:
  // `distance` and `gradient` come in as d_i(x) and grad d_i(x) and leave
  // guarded.
  void guard(const Eigen::Vector3d& x, double& distance,
             Eigen::Vector3d& gradient) const;

  // Analytic f and grad f (per model unit) at a model-space point at the
  // bind pose; 0 and a zero gradient outside the support box. Never throws.
  double value(const Eigen::Vector3d& x) const;
  void evaluate(const Eigen::Vector3d& x, double& value,
                Eigen::Vector3d& gradient) const;
};

// Fits the field of samples.joint (`mesh_positions`: the rig's rest mesh,
// #V by 3, whose part vertices set R). Throws isk::Error(kInvalidArgument) when
// fewer than 4 samples remain ("joint 'NAME': 3 samples, at least 4 are
// needed"); warnings name the joint.
BoneField fitBoneField(const Skeleton& skeleton,
                       const Matrix3Xf& mesh_positions,
                       const BonePartition& partition,
                       const BoneSamples& samples,
                       std::vector<std::string>* warnings = nullptr);

}  // namespace isk
