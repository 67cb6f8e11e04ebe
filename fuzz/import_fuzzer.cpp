// libFuzzer target over the import and rig-building path:
//
//   bytes -> a temporary file (extension from the content's magic) ->
//   isk::importRig -> Rig::validate -> partition, one-rings and mean value
//   weights -> each clip sampled -> LBS and DQS frames on the CPU reference
//   -> for small rigs, implicit fields (coarse grids) and one implicit
//   skinning frame on the CPU reference.
//
// The contract checked: every failure is an isk::Error with a documented
// code and a non-empty message; an imported rig always validates; anything
// else (a crash, a sanitizer report, another exception type, a rig that
// does not validate) is a finding. Run through `./run.sh fuzz [SECONDS]`.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "isk/core/error.hpp"
#include "isk/core/one_ring.hpp"
#include "isk/fields/bone_partition.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/pose.hpp"
#include "isk/rig/rig.hpp"
#include "isk/skinning/cpu_skinning.hpp"

namespace {

// The rigs the later stages run on are kept small so that one input stays
// in the millisecond range under the sanitizers.
constexpr int kMaxSkinningVertices = 20000;
constexpr int kMaxImplicitVertices = 1500;
constexpr int kMaxImplicitJoints = 24;

std::string g_dir;  // per-process temporary folder

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "isk fuzz finding: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

bool startsWith(const uint8_t* data, size_t size, const char* magic) {
  const size_t n = std::strlen(magic);
  return size >= n && std::memcmp(data, magic, n) == 0;
}

// The extension Assimp picks its importer by. Known magics keep their
// format; other inputs choose one of the formats the library documents by
// their first byte, so that the mutated seeds keep exercising those parsers
// rather than every importer Assimp carries.
const char* extensionFor(const uint8_t* data, size_t size) {
  if (startsWith(data, size, "glTF")) return ".glb";
  if (startsWith(data, size, "xof ")) return ".x";
  if (startsWith(data, size, "Kaydara FBX Binary")) return ".fbx";
  if (startsWith(data, size, "; FBX")) return ".fbx";
  if (startsWith(data, size, "<?xml") || startsWith(data, size, "<COLLADA"))
    return ".dae";
  if (startsWith(data, size, "{")) return ".gltf";
  static const char* const kFallback[] = {".glb", ".gltf", ".dae", ".x",
                                          ".fbx"};
  return kFallback[size == 0 ? 0 : data[0] % 5];
}

bool allFinite(const isk::Matrix3Xf& m) { return m.allFinite(); }

void checkError(const isk::Error& e, const char* stage) {
  if (std::strlen(e.what()) == 0) {
    finding(std::string(stage) + ": isk::Error with an empty message");
  }
  if (e.code() == isk::ErrorCode::kInternal) {
    finding(std::string(stage) + ": internal error: " + e.what());
  }
}

void runStages(const isk::Rig& rig) {
  if (isk::Validation v = rig.validate(); !v) {
    finding("importRig returned a rig that does not validate: " + v.reason());
  }
  const int vertices = rig.mesh.vertexCount();
  const int joints = rig.skeleton.jointCount();
  if (vertices > kMaxSkinningVertices) return;

  try {
    isk::BonePartition partition = isk::partitionMesh(rig);
    if (static_cast<int>(partition.vertex_joint.size()) != vertices)
      finding("partitionMesh: vertex_joint has the wrong size");
  } catch (const isk::Error& e) {
    checkError(e, "partitionMesh");
  }
  try {
    const isk::OneRings rings =
        isk::OneRings::build(rig.mesh.positions, rig.mesh.triangles);
    isk::RelaxationWeights::build(rings, rig.mesh.positions);
  } catch (const isk::Error& e) {
    checkError(e, "one-rings");
  }

  // Each clip at its start, middle, end and past its end; the bind pose.
  std::vector<isk::TransformList> poses;
  poses.push_back(isk::bindPoseSkinning(rig.skeleton));
  for (size_t c = 0; c < rig.clips.size() && c < 4; ++c) {
    const isk::AnimationClip& clip = rig.clips[c];
    for (double f : {0.0, 0.5, 1.0, 2.0}) {
      const double t = clip.start + f * clip.duration;
      const isk::TransformList locals = clip.sampleLocal(rig.skeleton, t);
      if (static_cast<int>(locals.size()) != joints)
        finding("sampleLocal: wrong number of transforms");
      poses.push_back(isk::skinningTransforms(
          rig.skeleton, isk::globalTransforms(rig.skeleton, locals)));
    }
  }

  try {
    isk::CpuSkinning skinning(rig.mesh, rig.weights, joints);
    skinning.run(isk::SkinningMethod::kDualQuaternion, poses.front());
    if (!allFinite(skinning.positions()))
      finding("DQS at the bind pose is not finite");
    for (const isk::TransformList& pose : poses) {
      for (auto method : {isk::SkinningMethod::kLinearBlend,
                          isk::SkinningMethod::kDualQuaternion}) {
        try {
          skinning.run(method, pose);
        } catch (const isk::Error& e) {
          checkError(e, "CpuSkinning::run");
        }
      }
    }
  } catch (const isk::Error& e) {
    checkError(e, "CpuSkinning");
  }

  if (vertices > kMaxImplicitVertices || joints > kMaxImplicitJoints) return;
  isk::ImplicitSkinnerOptions options;
  options.fields.grid_resolution = 8;
  options.fields.sampling.target_samples = 12;
  options.fields.threads = 1;
  options.tracking.rounds = 2;
  try {
    isk::CpuImplicitSkinner skinner(rig, options);
    skinner.run(poses.back());
    if (!allFinite(skinner.positions()))
      finding("implicit skinning produced a non-finite position");
  } catch (const isk::Error& e) {
    checkError(e, "CpuImplicitSkinner");
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const char* base = std::getenv("TMPDIR");
  std::string pattern =
      std::string(base && *base ? base : "/tmp") + "/isk-fuzz-XXXXXX";
  if (mkdtemp(pattern.data()) == nullptr) finding("cannot create " + pattern);
  g_dir = pattern;
  std::atexit([] { rmdir(g_dir.c_str()); });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = g_dir + "/input" + extensionFor(data, size);
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    if (size > 0 && std::fwrite(data, 1, size, f) != size) {
      std::fclose(f);
      finding("cannot write " + path);
    }
    std::fclose(f);
  } else {
    finding("cannot open " + path);
  }
  isk::Rig rig;
  try {
    rig = isk::importRig(path);
  } catch (const isk::Error& e) {
    checkError(e, "importRig");
    if (e.code() != isk::ErrorCode::kMalformedAsset &&
        e.code() != isk::ErrorCode::kIo) {
      finding(std::string("importRig threw ") + isk::errorCodeName(e.code()) +
              ": " + e.what());
    }
    std::remove(path.c_str());
    return 0;
  }
  std::remove(path.c_str());
  runStages(rig);
  return 0;
}
