// Geometric skinning and vertex normals on the CPU: the single-thread
// reference twin of ClSkinning (isk/cl/skinning.hpp), with the same calls.
//
// It chains the reference jobs SkinningJob and VertexNormalsJob over a copy
// of the mesh's static data, so tests, benchmarks and samples run either
// backend through one interface.
#pragma once

#include "isk/core/mesh.hpp"
#include "isk/core/types.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/rig/skin_weights.hpp"
#include "isk/skinning/skinning.hpp"

namespace isk {

// One character's geometric skinning on the CPU (single thread).
class CpuSkinning {
 public:
  // Validates the mesh and weights (isk::Error kInvalidArgument) and keeps a
  // copy of them; `joint_count` is the length of the transform lists run()
  // takes.
  CpuSkinning(const Mesh& mesh, const SkinWeights& weights, int joint_count);

  // Skins the rest mesh with `skinning` (#joints transforms) and, when asked,
  // recomputes area-weighted normals from the skinned positions (the skinned
  // normals are the fallback); otherwise the normals are the skinned ones.
  // Throws isk::Error(kInvalidArgument) for a pose of the wrong size or with
  // non-finite transforms.
  void run(SkinningMethod method, const TransformList& skinning,
           bool recompute_normals = true);

  // Results of the last run, #V by 3.
  const Matrix3Xf& positions() const { return positions_; }
  const Matrix3Xf& normals() const { return normals_; }
  // Copies, for symmetry with ClSkinning. Throw isk::Error(kInvalidArgument)
  // before the first run() and on a moved-from object, as run() does.
  void readPositions(Matrix3Xf& out) const;
  void readNormals(Matrix3Xf& out) const;

  // Milliseconds per stage of the last run.
  const SkinningStageTimes& lastTimes() const { return times_; }
  // What the constructor kept: the rest normals (#V by 3) and the weights.
  const Matrix3Xf& restNormals() const { return rest_normals_; }
  const SkinWeights& weights() const { return weights_; }
  // #V of the mesh given to the constructor.
  int vertexCount() const { return static_cast<int>(rest_positions_.rows()); }

 private:
  void checkUsable(const char* what, bool needs_run) const;

  Matrix3Xf rest_positions_, rest_normals_;
  TriangleMatrix triangles_;
  SkinWeights weights_;
  int joint_count_ = 0;
  VertexTriangleAdjacency adjacency_;
  Matrix3Xf positions_, skinned_normals_, normals_;
  SkinningStageTimes times_;
  bool has_run_ = false;
};

}  // namespace isk
