// Triangle mesh of a skinned character.
//
// Several meshes of one scene are merged into one skin: their vertices are
// appended in scene order, each brought into scene (world) space by its node's
// transform at the bind pose; `parts` remembers where each came from so that
// messages and exports can name the mesh.
#pragma once

#include <string>
#include <vector>

#include "isk/core/types.hpp"
#include "isk/core/validation.hpp"

namespace isk {

// Where one source mesh's vertices and triangles sit in the merged Mesh.
struct MeshPart {
  std::string name;  // mesh name in the source file
  int first_vertex = 0;
  int vertex_count = 0;
  int first_triangle = 0;
  int triangle_count = 0;
};

// One skin: every triangle mesh of the source, merged.
struct Mesh {
  Matrix3Xf positions;       // #V by 3, model space
  Matrix3Xf normals;         // #V by 3, unit length
  TriangleMatrix triangles;  // #F by 3, counter-clockwise seen from outside
  std::vector<MeshPart> parts;

  int vertexCount() const { return static_cast<int>(positions.rows()); }  // #V
  int triangleCount() const {                                             // #F
    return static_cast<int>(triangles.rows());
  }

  // Checks shapes, index ranges and finiteness; names the first bad vertex or
  // triangle (and its part).
  Validation validate() const;

  // Name of the part holding vertex `v`, for messages ("mesh 'Body'").
  std::string describeVertex(int v) const;
};

}  // namespace isk
