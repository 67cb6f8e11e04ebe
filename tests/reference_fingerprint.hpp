// The CPU reference of the whole pipeline on a small procedural rig, reduced
// to one line: shared by the fault tests and isk_no_device_probe, which runs
// it in a process that sees no OpenCL platform.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "isk/implicit_skinner.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"

namespace isk::test {

// FNV-1a over the bytes of `m`.
inline uint64_t fingerprintOf(const Matrix3Xf& m, uint64_t hash) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(m.data());
  for (size_t i = 0; i < static_cast<size_t>(m.size()) * sizeof(float); ++i)
    hash = (hash ^ bytes[i]) * 1099511628211ull;
  return hash;
}

// "reference <hash> finite <0|1>": LBS, DQS and implicit skinning (fields
// built, tracking, normals) of a 2-bone cylinder at three times of its
// clip, every result hashed bit for bit.
inline std::string referenceFingerprint() {
  CylinderRigOptions cylinder;
  cylinder.rings = 16;
  cylinder.segments = 12;
  const Rig rig = makeCylinderRig(cylinder);
  const AnimationClip& clip = rig.clips.at(0);
  ImplicitSkinnerOptions options;
  options.fields.grid_resolution = 16;
  CpuSkinning skinning(rig.mesh, rig.weights, rig.skeleton.jointCount());
  CpuImplicitSkinner skinner(rig, options);
  uint64_t hash = 1469598103934665603ull;
  bool finite = true;
  for (double f : {0.0, 0.5, 1.0}) {
    const TransformList pose = skinningTransforms(
        rig.skeleton,
        globalTransforms(
            rig.skeleton,
            clip.sampleLocal(rig.skeleton, clip.start + f * clip.duration)));
    for (auto method :
         {SkinningMethod::kLinearBlend, SkinningMethod::kDualQuaternion}) {
      skinning.run(method, pose);
      hash = fingerprintOf(skinning.positions(), hash);
      hash = fingerprintOf(skinning.normals(), hash);
      finite = finite && skinning.positions().allFinite();
    }
    skinner.run(pose);
    hash = fingerprintOf(skinner.positions(), hash);
    hash = fingerprintOf(skinner.normals(), hash);
    finite = finite && skinner.positions().allFinite() &&
             skinner.normals().allFinite();
  }
  char line[64];
  std::snprintf(line, sizeof(line), "reference %016llx finite %d",
                static_cast<unsigned long long>(hash), finite ? 1 : 0);
  return line;
}

}  // namespace isk::test
