// Area-weighted vertex normals of a triangle mesh, CPU reference of
// kernels/normals.cl.
//
// Each triangle's (unnormalized) cross product is taken once; each vertex
// sums those of its incident triangles, read through a vertex-to-triangle
// adjacency built once, and normalizes. A vertex whose sum vanishes (no
// triangle, or only degenerate ones) takes its fallback normal instead.
#pragma once

#include <cstdint>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"

namespace isk {

// Vertex -> incident triangles, compressed rows.
struct VertexTriangleAdjacency {
  std::vector<uint32_t> offsets;    // #V + 1
  std::vector<uint32_t> triangles;  // 3 * #F entries

  // `triangles`: #F by 3 indices, which must lie in [0, vertex_count): they
  // are not checked (Mesh::validate does). Other uses may add entries, as
  // long as the rows stay in order (the tracking mesh welds seams so).
  static VertexTriangleAdjacency build(const TriangleMatrix& triangles,
                                       int vertex_count);
};

// Area-weighted normals of one frame (single thread). The pointed-to inputs
// must outlive run().
struct VertexNormalsJob {
  const Matrix3Xf* positions = nullptr;                // #V by 3
  const TriangleMatrix* triangles = nullptr;           // #F by 3
  const VertexTriangleAdjacency* adjacency = nullptr;  // built for them
  const Matrix3Xf* fallback_normals = nullptr;         // #V by 3
  Matrix3Xf* out_normals = nullptr;                    // resized to #V by 3

  // Names the first missing input or mismatched size.
  Validation validate() const;
  // Throws isk::Error(kInvalidArgument) when validate() fails.
  void run() const;
};

}  // namespace isk
