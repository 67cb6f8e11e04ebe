// Loading rigs from files with Assimp (glTF/GLB, FBX, COLLADA, DirectX .x and
// every other format Assimp reads).
//
// What the loader does with the scene:
// - every triangle mesh is merged into one skin (Mesh's header says how);
//   point and line primitives are dropped with a warning;
// - a mesh without bones that hangs below a joint is attached rigidly to that
//   joint; other meshes without bones are skipped with a warning;
// - the skeleton is every bone node and its ancestors below the scene root,
//   plus the childless non-mesh nodes below bones (bone tips);
// - weights are normalized per vertex, with a warning when sums were off;
// - uniform scale in bind transforms (unit conversions) is accepted; a
//   non-uniform scale or shear in a bind transform is an error.
#pragma once

#include <functional>
#include <string>

#include "isk/rig.hpp"

namespace isk {

// What importRig can be told.
struct ImportOptions {
  // Weight sums further than this from 1 are reported when normalized.
  float weight_sum_tolerance = 1e-3f;
  // Called from the loading thread as work goes on: `stage` is "reading"
  // (Assimp's parser), "processing" (triangulation, joining) or "building"
  // (skin, skeleton, clips); `fraction` grows from 0 to 1 within a stage.
  std::function<void(const char* stage, float fraction)> progress;
};

// Loads `path`. Throws isk::Error: kIo when the file cannot be read,
// kMalformedAsset when its content is unusable (no mesh, no skeleton, a
// vertex without weight, NaN/inf, a non-rigid bind transform...). The message
// names the file and the mesh, joint or vertex.
Rig importRig(const std::string& path, const ImportOptions& options = {});

}  // namespace isk
