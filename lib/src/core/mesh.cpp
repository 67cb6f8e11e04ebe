#include "isk/core/mesh.hpp"

#include <cmath>
#include <string>

namespace isk {

std::string Mesh::describeVertex(int v) const {
  for (const MeshPart& part : parts) {
    if (v >= part.first_vertex && v < part.first_vertex + part.vertex_count) {
      return "mesh '" + part.name + "' vertex " +
             std::to_string(v - part.first_vertex);
    }
  }
  return "vertex " + std::to_string(v);
}

Validation Mesh::validate() const {
  const int n = vertexCount();
  if (n == 0) return Validation::fail("the mesh has no vertex");
  if (triangleCount() == 0) return Validation::fail("the mesh has no triangle");
  if (normals.rows() != n) {
    return Validation::fail("normals have " + std::to_string(normals.rows()) +
                            " rows for " + std::to_string(n) + " vertices");
  }
  for (int v = 0; v < n; ++v) {
    if (!positions.row(v).allFinite()) {
      return Validation::fail(describeVertex(v) + " has a non-finite position");
    }
    if (!normals.row(v).allFinite()) {
      return Validation::fail(describeVertex(v) + " has a non-finite normal");
    }
  }
  for (int f = 0; f < triangleCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = triangles(f, k);
      if (v < 0 || v >= n) {
        return Validation::fail("triangle " + std::to_string(f) +
                                " refers to vertex " + std::to_string(v) +
                                " (the mesh has " + std::to_string(n) + ")");
      }
    }
  }
  return Validation::ok();
}

}  // namespace isk
