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

#include <cstdint>
#include <functional>
#include <string>

#include "isk/rig/rig.hpp"

namespace isk {

// What importRig can be told.
struct ImportOptions {
  // Weight sums further than this from 1 are reported when normalized.
  float weight_sum_tolerance = 1e-3f;
  // Called from the loading thread as work goes on: `stage` is "reading"
  // (Assimp's parser), "processing" (triangulation, joining) or "building"
  // (skin, skeleton, clips); `fraction` grows from 0 to 1 within a stage.
  std::function<void(const char* stage, float fraction)> progress;

  // Import in a child process (POSIX fork), so that a file that makes
  // Assimp's parsers hang, crash or allocate without bound cannot take the
  // application with it. Some corrupt files do: Assimp 5.2 loops forever on a
  // COLLADA index list holding a non-number and cannot be cancelled. The rig
  // crosses back over a pipe; progress still arrives, on the calling thread.
  // A crash in the child is thrown as kMalformedAsset. Costs the fork (page
  // tables copied; each page the child or the application writes afterwards
  // is copied once) and the transfer: see Import/*/isolated in bench/.
  // Recommended for files the application did not make; with other threads
  // running, give a time limit too (a lock one of them held at the fork
  // stays held in the child).
  bool isolate = false;
  // Seconds the import may take; past them its process is killed and
  // kLimitExceeded thrown. 0: no limit. Implies isolate.
  double time_limit_seconds = 0;
  // Bytes of memory (address space) the import may take on top of what the
  // application has; beyond them kLimitExceeded is thrown. 0: no limit.
  // Implies isolate.
  uint64_t memory_limit_bytes = 0;
};

// Loads `path`. Throws isk::Error: kIo when the file cannot be read,
// kMalformedAsset when its content is unusable (no mesh, no skeleton, a
// vertex without weight, NaN/inf, a non-rigid bind transform...) or crashed
// an isolated import, kLimitExceeded when an isolated import passed its time
// or memory limit, kInvalidArgument for a negative or non-finite limit. The
// message names the file and the mesh, joint or vertex. An isolated import
// returns the same rig, bit for bit, as one in the calling process.
Rig importRig(const std::string& path, const ImportOptions& options = {});

}  // namespace isk
