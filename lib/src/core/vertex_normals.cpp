#include "isk/core/vertex_normals.hpp"

#include <cfloat>
#include <cmath>
#include <string>

namespace isk {

VertexTriangleAdjacency VertexTriangleAdjacency::build(
    const TriangleMatrix& triangles, int vertex_count) {
  VertexTriangleAdjacency adjacency;
  adjacency.offsets.assign(vertex_count + 1, 0);
  for (int f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) ++adjacency.offsets[triangles(f, k) + 1];
  }
  for (int v = 0; v < vertex_count; ++v)
    adjacency.offsets[v + 1] += adjacency.offsets[v];
  adjacency.triangles.resize(adjacency.offsets[vertex_count]);
  std::vector<uint32_t> cursor(adjacency.offsets.begin(),
                               adjacency.offsets.end() - 1);
  for (int f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      adjacency.triangles[cursor[triangles(f, k)]++] = f;
  }
  return adjacency;
}

Validation VertexNormalsJob::validate() const {
  if (!positions || !triangles || !adjacency || !fallback_normals ||
      !out_normals) {
    return Validation::fail("an input or output of the normals job is not set");
  }
  const int n = static_cast<int>(positions->rows());
  if (fallback_normals->rows() != n) {
    return Validation::fail("fallback normals have " +
                            std::to_string(fallback_normals->rows()) +
                            " rows for " + std::to_string(n) + " vertices");
  }
  // Built by build() (3 entries a triangle) or welded across seams (more):
  // rows must cover the list and name triangles of this mesh.
  if (adjacency->offsets.size() != static_cast<size_t>(n) + 1 ||
      adjacency->offsets.back() != adjacency->triangles.size()) {
    return Validation::fail("the adjacency was not built for this mesh");
  }
  for (const uint32_t t : adjacency->triangles) {
    if (t >= static_cast<uint32_t>(triangles->rows())) {
      return Validation::fail("the adjacency names triangle " +
                              std::to_string(t) + " of a mesh of " +
                              std::to_string(triangles->rows()));
    }
  }
  return Validation::ok();
}

void VertexNormalsJob::run() const {
  validate().throwIfFailed("VertexNormalsJob");
  const int n = static_cast<int>(positions->rows());
  // Each triangle's cross product once, then the sums in adjacency order:
  // the kernels' two launches, and the same sums as one product per corner.
  const int triangle_count = static_cast<int>(triangles->rows());
  Matrix3Xf triangle_normals(triangle_count, 3);
  for (int t = 0; t < triangle_count; ++t) {
    const Eigen::Vector3f a =
        positions->row(triangles->coeff(t, 0)).transpose();
    const Eigen::Vector3f b =
        positions->row(triangles->coeff(t, 1)).transpose();
    const Eigen::Vector3f c =
        positions->row(triangles->coeff(t, 2)).transpose();
    triangle_normals.row(t) = (b - a).cross(c - a).transpose();
  }
  out_normals->resize(n, 3);
  for (int v = 0; v < n; ++v) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (uint32_t i = adjacency->offsets[v]; i < adjacency->offsets[v + 1]; ++i)
      sum += triangle_normals.row(adjacency->triangles[i]).transpose();
    const float len = std::sqrt(sum.dot(sum));
    if (len > FLT_MIN && std::isfinite(len)) {  // overflow: the fallback
      out_normals->row(v) = sum / len;
    } else {
      out_normals->row(v) = fallback_normals->row(v);
    }
  }
}

}  // namespace isk
