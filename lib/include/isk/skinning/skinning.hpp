// Geometric skinning, CPU reference: linear blend skinning (LBS) and dual
// quaternion skinning (DQS, Kavan et al. 2008).
//
// The OpenCL kernels in kernels/skinning.cl do the same job with the same
// formulas; tests compare the two.
//
// DQS: per vertex the first (largest) influence's rotation is the pivot; any
// joint dual quaternion whose real part has a negative dot product with it is
// negated before blending; the blend is divided by the norm of its real part.
// LBS normals use the cofactor matrix of the blended linear part (the inverse
// transpose up to scale), then are normalized.
#pragma once

#include <string>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"
#include "isk/rig/skin_weights.hpp"

namespace isk {

// Geometric skinning: linear blend (LBS) or dual quaternion (DQS).
enum class SkinningMethod { kLinearBlend, kDualQuaternion };

// Milliseconds spent per stage of one frame (ClSkinning: from OpenCL
// profiling events; CpuSkinning: host wall time).
struct SkinningStageTimes {
  double upload_ms = 0;    // joint transforms to the device (0 on the CPU)
  double skinning_ms = 0;  // skinning
  double normals_ms = 0;   // normals (0 when not recomputed)
  double readback_ms = 0;  // last readPositions + readNormals
};

const char* skinningMethodName(SkinningMethod method);  // "lbs" / "dqs"

// Packs skinning transforms for the kernels: LBS takes the top 3 rows of each
// 4x4 matrix (12 floats per joint, row-major), DQS 8 floats per joint.
std::vector<float> packJointTransforms(SkinningMethod method,
                                       const TransformList& skinning);

// One frame of geometric skinning on the CPU (single thread). The pointed-to
// inputs must outlive run().
struct SkinningJob {
  SkinningMethod method = SkinningMethod::kDualQuaternion;
  const Matrix3Xf* rest_positions = nullptr;  // #V by 3, bind pose
  const Matrix3Xf* rest_normals = nullptr;    // #V by 3
  const SkinWeights* weights = nullptr;       // #V rows
  const TransformList* skinning = nullptr;    // #joints
  Matrix3Xf* out_positions = nullptr;         // resized to #V by 3
  Matrix3Xf* out_normals = nullptr;           // resized to #V by 3

  // Names the first missing input or mismatched size, or a non-finite
  // transform.
  Validation validate() const;
  // Throws isk::Error(kInvalidArgument) when validate() fails.
  void run() const;
};

// The inverse of skinning, point by point: `posed` (#V by 3, at the pose
// `skinning`) carried back to rest space by the inverse of each vertex's
// blended transform (DQS: the blended unit dual quaternion's; LBS: the
// blended matrix's, the point kept as it is where that matrix is singular).
// Skinning the result with the same method, weights and pose gives `posed`
// back up to rounding. History-dependent tracking keeps its vertices in rest
// space between frames with it (isk/implicit_skinner.hpp). Throws
// isk::Error(kInvalidArgument) as SkinningJob::run does for sizes that do not
// match or a non-finite pose. kernels/skinning.cl's unskin_lbs and
// unskin_dqs do the same job.
void unskinPoints(SkinningMethod method, const SkinWeights& weights,
                  const TransformList& skinning, const Matrix3Xf& posed,
                  Matrix3Xf& rest);

}  // namespace isk
