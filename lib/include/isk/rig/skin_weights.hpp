// Sparse skinning weights: any number of influences per vertex.
//
// Compressed rows (CSR): the influences of vertex v are the entries
// offsets[v] .. offsets[v+1]-1 of `joints` and `weights`. Within a vertex the
// influences are sorted by decreasing weight, so the first one is the
// dominant joint (the pivot of dual quaternion skinning).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "isk/core/validation.hpp"

namespace isk {

// The weights of every vertex of a mesh (#V rows).
struct SkinWeights {
  std::vector<uint32_t> offsets;  // #V + 1
  std::vector<uint32_t> joints;   // #influences, joint indices
  std::vector<float> weights;     // #influences, sum to 1 per vertex

  // #V (0 when offsets is empty).
  int vertexCount() const {
    return offsets.empty() ? 0 : static_cast<int>(offsets.size()) - 1;
  }
  // Influences of vertex v (0 <= v < vertexCount(), not checked).
  int influenceCount(int v) const { return offsets[v + 1] - offsets[v]; }
  // The largest influenceCount over the vertices (0 when there is none).
  int maxInfluences() const;

  // Builds the compressed rows from per-vertex (joint, weight) lists; drops
  // zero weights and merges repeated joints of one vertex. Does not sort or
  // normalize (sortByWeight, normalize).
  static SkinWeights fromLists(
      const std::vector<std::vector<std::pair<int, float>>>& per_vertex);

  // Sorts each vertex's influences by decreasing weight (ties: lower joint).
  void sortByWeight();

  // Normalizes each vertex's weights to sum 1. Returns how many vertices had a
  // sum off by more than `tolerance` and the range of the sums seen.
  struct NormalizeReport {
    int off_count = 0;
    float min_sum = 1.f;
    float max_sum = 1.f;
  };
  NormalizeReport normalize(float tolerance = 1e-3f);

  // Checks shapes, joint indices < joint_count, finite positive weights, at
  // least one influence per vertex and sums of 1 (within 1e-3); names the
  // first bad vertex.
  Validation validate(int vertex_count, int joint_count) const;
};

}  // namespace isk
