// Animated glTF 2.0 (.glb) export: several deformed copies of one mesh,
// side by side, each playing its frames.
//
// One binary glTF file (JSON chunk + BIN chunk) with one scene holding one
// node per track (e.g. LBS, DQS and implicit skinning of the same clip),
// translated by the track's offset. Each track is a mesh whose base is frame
// 0 and whose morph target k holds frame k minus frame 0 (positions and
// normals; target 0 is all zero). One animation drives the mesh weights of
// every track with STEP interpolation: at frame k's time, weight k is 1 and
// every other weight 0, so any glTF viewer (three.js editor, Blender,
// gltf-viewer, Windows 3D Viewer) plays the frames exactly as written. The
// spec's required fields are present: accessor min/max for every POSITION
// (base and targets) and for the animation's time input, buffer views
// aligned to 4 bytes, byteLength consistent with the BIN chunk.
//
// The file is written to a temporary name beside `path` and renamed when
// complete (isk::writeTextFile).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "isk/core/types.hpp"

namespace isk {

struct GltfTrack {
  std::string name;                    // node and mesh name, e.g. "implicit"
  Eigen::Vector3f offset = {0, 0, 0};  // node translation
  std::vector<Matrix3Xf> positions;    // per frame, #V by 3
  std::vector<Matrix3Xf> normals;      // per frame, #V by 3 (empty: none)
};

// Writes `tracks` (each with one frame per entry of `times`, seconds,
// increasing, and #V rows matching every frame and `triangles`) to `path`
// as a .glb. Throws isk::Error(kInvalidArgument) for inconsistent inputs
// (naming the track and frame) and isk::Error(kIo) naming the path.
void writeAnimatedGltf(const std::string& path, const TriangleMatrix& triangles,
                       const std::vector<GltfTrack>& tracks,
                       const std::vector<double>& times);

// `times` when strictly increasing, else 30 frames per second from 0 (a
// clip without duration): what writeAnimatedGltf accepts.
std::vector<double> gltfFrameTimes(const std::vector<double>& times);

// The x offset that places track i beside track i - 1: 1.2 times the
// x extent of every frame of `positions` (at least 1e-3).
float gltfTrackSpacing(const std::vector<Matrix3Xf>& positions);

}  // namespace isk
