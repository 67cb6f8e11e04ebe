// One-rings of a skin mesh and their mean value coordinates, the static data
// of tangential relaxation and localized smoothing (Vaillant et al. 2013,
// section 5, eq. 5 and 7; mean value coordinates: Floater 2003, Hormann and
// Floater 2006).
//
// Coincident vertices are welded first: imported meshes split vertices along
// UV seams, and the two copies must move as one or the skin cracks. Each
// group of vertices at the same rest position (bitwise-equal floats) has a
// representative, its smallest index; only representatives carry a ring and
// are tracked, the others copy their representative's result.
//
// Ring kinds:
//   kClosed     a manifold interior vertex: neighbours ordered counter-
//               clockwise seen from outside (mesh connectivity by OpenMesh);
//   kBoundary   on an open border: neighbours ordered, the fan is open;
//   kIrregular  touching a non-manifold edge or vertex: neighbours unordered;
//   kIsolated   in no triangle (no neighbour);
//   kDuplicate  not a representative (empty ring).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "isk/core/types.hpp"

namespace isk {

// The kind of a vertex's ring (see above).
enum class RingKind : uint8_t {
  kClosed = 0,
  kBoundary = 1,
  kIrregular = 2,
  kIsolated = 3,
  kDuplicate = 4,
};

const char* ringKindName(RingKind kind);  // "closed", "boundary", ...

// #V: for each vertex of `positions` (#V by 3), the smallest index at the
// same position (bitwise-equal floats): the welded mesh's vertex.
std::vector<int> weldedRepresentatives(const Matrix3Xf& positions);

// The one-ring of every vertex, in compressed rows.
struct OneRings {
  std::vector<int> representative;  // #V: smallest index at the same spot
  std::vector<uint32_t> offsets;    // #V + 1, rows of `neighbours`
  std::vector<int> neighbours;      // representative vertex indices
  std::vector<RingKind> kinds;      // #V

  int vertexCount() const { return static_cast<int>(kinds.size()); }
  // Number of vertices of that kind.
  int count(RingKind kind) const;

  // Welds, then builds the rings of `triangles` (#F by 3) over `positions`
  // (#V by 3, the rest pose). Degenerate triangles (two corners welded
  // together) are left out. Throws isk::Error(kInvalidArgument) naming the
  // triangle for an index out of range.
  static OneRings build(const Matrix3Xf& positions,
                        const TriangleMatrix& triangles);
};

// How tangential relaxation treats each vertex (documented fallbacks).
enum class RelaxationRule : uint8_t {
  kMeanValue = 0,    // mean value coordinates, all positive
  kClampedMean = 1,  // some came out negative (non-star-shaped ring seen in
                     // the tangent plane): negatives set to 0, renormalized
  kUniform = 2,      // irregular ring, or every weight <= 0: 1 / #ring
  kFixed = 3,        // boundary, isolated or duplicate: not relaxed (an
                     // open fan has no centroid that keeps the border)
};

// "mean value", "clamped", "uniform", "fixed".
const char* relaxationRuleName(RelaxationRule rule);

// Per-vertex weights of tangential relaxation (eq. 5): v moves toward
// sum_j w_j q_j over its ring, the weights of a ring summing to 1.
struct RelaxationWeights {
  std::vector<float> weights;         // aligned with OneRings::neighbours
  std::vector<RelaxationRule> rules;  // #V

  // Number of vertices under that rule.
  int count(RelaxationRule rule) const;
  // One line: "12000 mean value, 30 clamped, 2 uniform, 40 fixed".
  std::string describe() const;

  // Mean value coordinates of each representative's ring, projected on its
  // tangent plane at the rest pose (the plane normal to the ring's area-
  // weighted normal), so that v = sum_j w_j q_j there.
  // `rest_positions`: #V by 3, those the rings were built from.
  static RelaxationWeights build(const OneRings& rings,
                                 const Matrix3Xf& rest_positions);
};

}  // namespace isk
