// The C++ side of the Python module's bit-for-bit tests
// (python/tests/test_frames.py): skins a rig's clip through the C++ API as
// a C++ program would, and writes every frame exactly.
//
//   isk_py_reference_frames RIG METHOD DEVICE FRAMES OUT [OPTION...]
//
// RIG: builtin:NAME or a file (isk::importRig); METHOD: lbs, dqs or
// implicit; DEVICE: opencl or reference; FRAMES: frame count, spread over
// the clip from its start to its end. Options: clip=INDEX (default 0),
// bend=DEGREES (isk::makeBendClip over 1 s instead of a clip),
// operator=union|blend|bulge, cache=DIR (the field cache).
//
// OUT, little-endian: int32 frames, int32 #V; per frame float64 time,
// int32 contact count (0 without implicit skinning), #V * 3 float32
// positions, #V * 3 float32 normals.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/error.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/pose.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tools/procedural.hpp"

namespace {

void write(std::FILE* file, const void* data, size_t bytes) {
  if (std::fwrite(data, 1, bytes, file) != bytes) {
    throw isk::Error(isk::ErrorCode::kIo, "short write");
  }
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc < 6) {
    std::fprintf(stderr,
                 "usage: %s RIG lbs|dqs|implicit opencl|reference FRAMES OUT "
                 "[clip=I] [bend=DEG] [operator=OP] [cache=DIR]\n",
                 argv[0]);
    return 2;
  }
  const std::string input = argv[1], method = argv[2], device = argv[3];
  const int frames = std::stoi(argv[4]);
  int clip_index = 0;
  double bend = -1;
  isk::ImplicitSkinnerOptions options;
  for (int i = 6; i < argc; ++i) {
    const std::string arg = argv[i];
    const std::string key = arg.substr(0, arg.find('='));
    const std::string value = arg.substr(arg.find('=') + 1);
    if (key == "clip") {
      clip_index = std::stoi(value);
    } else if (key == "bend") {
      bend = std::stod(value);
    } else if (key == "operator") {
      if (!isk::parseCompositionOperator(
              value, &options.fields.composition.default_operator)) {
        throw isk::Error(isk::ErrorCode::kInvalidArgument, "operator " + value);
      }
    } else if (key == "cache") {
      options.fields.cache = true;
      options.fields.cache_folder = value;
    } else {
      throw isk::Error(isk::ErrorCode::kInvalidArgument, "option " + arg);
    }
  }

  const isk::Rig rig = input.rfind("builtin:", 0) == 0
                           ? isk::makeBuiltinRig(input.substr(8))
                           : isk::importRig(input);
  const isk::AnimationClip clip =
      bend >= 0
          ? isk::makeBendClip(rig.skeleton,
                              static_cast<float>(bend * M_PI / 180.0), 1.0)
          : rig.clips.at(clip_index);

  const bool reference = device == "reference";
  std::shared_ptr<isk::ClContext> context;
  if (!reference) context = isk::ClContext::create("");
  std::unique_ptr<isk::ImplicitSkinner> implicit;
  std::unique_ptr<isk::CpuImplicitSkinner> implicit_reference;
  std::unique_ptr<isk::ClSkinning> geometric;
  std::unique_ptr<isk::CpuSkinning> geometric_reference;
  const int joints = rig.skeleton.jointCount();
  if (method == "implicit") {
    if (reference) {
      implicit_reference =
          std::make_unique<isk::CpuImplicitSkinner>(rig, options);
    } else {
      implicit = std::make_unique<isk::ImplicitSkinner>(context, rig, options);
    }
  } else if (reference) {
    geometric_reference =
        std::make_unique<isk::CpuSkinning>(rig.mesh, rig.weights, joints);
  } else {
    geometric = std::make_unique<isk::ClSkinning>(context, rig.mesh,
                                                  rig.weights, joints);
  }
  const isk::SkinningMethod geometric_method =
      method == "lbs" ? isk::SkinningMethod::kLinearBlend
                      : isk::SkinningMethod::kDualQuaternion;

  std::FILE* file = std::fopen(argv[5], "wb");
  if (!file) throw isk::Error(isk::ErrorCode::kIo, "cannot open the output");
  const int32_t header[2] = {frames, rig.mesh.vertexCount()};
  write(file, header, sizeof header);
  isk::Matrix3Xf positions, normals;
  for (int i = 0; i < frames; ++i) {
    const double t =
        frames > 1 ? clip.start + clip.duration * i / (frames - 1) : clip.start;
    const isk::TransformList pose = isk::skinningTransforms(
        rig.skeleton,
        isk::globalTransforms(rig.skeleton, clip.sampleLocal(rig.skeleton, t)));
    int32_t contacts = 0;
    if (implicit) {
      implicit->run(pose);
      implicit->readPositions(positions);
      implicit->readNormals(normals);
      contacts = implicit->contactCount();
    } else if (implicit_reference) {
      implicit_reference->run(pose);
      implicit_reference->readPositions(positions);
      implicit_reference->readNormals(normals);
      contacts = implicit_reference->contactCount();
    } else if (geometric) {
      geometric->run(geometric_method, pose, /*recompute_normals=*/true);
      geometric->readPositions(positions);
      geometric->readNormals(normals);
    } else {
      geometric_reference->run(geometric_method, pose,
                               /*recompute_normals=*/true);
      geometric_reference->readPositions(positions);
      geometric_reference->readNormals(normals);
    }
    write(file, &t, sizeof t);
    write(file, &contacts, sizeof contacts);
    write(file, positions.data(), sizeof(float) * positions.size());
    write(file, normals.data(), sizeof(float) * normals.size());
  }
  if (std::fclose(file) != 0) {
    throw isk::Error(isk::ErrorCode::kIo, "cannot close the output");
  }
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "isk_py_reference_frames: %s\n", e.what());
  return 1;
}
