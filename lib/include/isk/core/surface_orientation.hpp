// Which side of a rest mesh is its outside.
//
// Mesh promises triangles wound counter-clockwise seen from outside; files do
// not always keep that promise (an exporter's flipped winding, a mirrored
// node). The fields' Hermite samples take their normals from the winding
// (Vaillant et al. 2013, section 4.1), so a surface wound the other way round
// gets fields that are high outside the skin and low inside it, and the
// tracking then pulls the skin into a crumpled tube.
//
// Per connected component of the welded mesh (vertices at bitwise-equal
// positions are one): its signed volume about its centroid. A component is
// inside out when that volume is negative and the component is closed enough
// for the sign to mean something: its vector area (the sum of its triangles'
// area vectors, zero for a closed surface) is at most kMaxOpenness of its
// total area. Open sheets (a wing membrane, a card) keep their winding.
#pragma once

#include <cstdint>
#include <vector>

#include "isk/core/mesh.hpp"

namespace isk {

struct SurfaceOrientation {
  static constexpr double kMaxOpenness = 0.25;

  // A connected component wound inside out.
  struct InsideOut {
    int vertex = 0;  // one of its vertices, for messages
    int triangle_count = 0;
    double signed_volume = 0;  // negative
  };

  std::vector<int8_t> triangle_sign;  // #F: +1 as wound, -1 inside out
  int component_count = 0;            // connected components, welded
  std::vector<InsideOut> inside_out;  // in order of their first triangle

  // Orients `mesh` (its rest positions and triangles; Mesh::validate'd).
  static SurfaceOrientation of(const Mesh& mesh);
};

}  // namespace isk
