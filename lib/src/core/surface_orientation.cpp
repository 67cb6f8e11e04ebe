#include "isk/core/surface_orientation.hpp"

#include <numeric>

#include "isk/core/one_ring.hpp"

namespace isk {

namespace {

int findRoot(std::vector<int>& parent, int a) {
  while (parent[a] != a) {
    parent[a] = parent[parent[a]];
    a = parent[a];
  }
  return a;
}

}  // namespace

SurfaceOrientation SurfaceOrientation::of(const Mesh& mesh) {
  const int vertex_count = mesh.vertexCount();
  const int triangle_count = mesh.triangleCount();
  SurfaceOrientation out;
  out.triangle_sign.assign(triangle_count, 1);
  const std::vector<int> welded = weldedRepresentatives(mesh.positions);
  std::vector<int> parent(vertex_count);
  std::iota(parent.begin(), parent.end(), 0);
  for (int t = 0; t < triangle_count; ++t)
    for (int c = 1; c < 3; ++c) {
      const int a = findRoot(parent, welded[mesh.triangles(t, 0)]);
      const int b = findRoot(parent, welded[mesh.triangles(t, c)]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }

  // Per component, in order of its first triangle: the centroid of its
  // corners, then its signed volume about it, vector area and area.
  std::vector<int> component_of(vertex_count, -1);
  std::vector<int> triangle_component(triangle_count);
  std::vector<int> first_vertex;
  for (int t = 0; t < triangle_count; ++t) {
    const int root = findRoot(parent, welded[mesh.triangles(t, 0)]);
    if (component_of[root] < 0) {
      component_of[root] = static_cast<int>(first_vertex.size());
      first_vertex.push_back(mesh.triangles(t, 0));
    }
    triangle_component[t] = component_of[root];
  }
  const size_t components = first_vertex.size();
  out.component_count = static_cast<int>(components);
  auto corner = [&](int t, int c) -> Eigen::Vector3d {
    return mesh.positions.row(mesh.triangles(t, c)).transpose().cast<double>();
  };
  std::vector<Eigen::Vector3d> centroid(components, Eigen::Vector3d::Zero());
  std::vector<int> counts(components, 0);
  for (int t = 0; t < triangle_count; ++t) {
    for (int c = 0; c < 3; ++c) centroid[triangle_component[t]] += corner(t, c);
    counts[triangle_component[t]] += 3;
  }
  for (size_t k = 0; k < components; ++k) centroid[k] /= counts[k];
  std::vector<double> volume(components, 0), area(components, 0);
  std::vector<Eigen::Vector3d> vector_area(components, Eigen::Vector3d::Zero());
  for (int t = 0; t < triangle_count; ++t) {
    const int k = triangle_component[t];
    const Eigen::Vector3d a = corner(t, 0) - centroid[k],
                          b = corner(t, 1) - centroid[k],
                          c = corner(t, 2) - centroid[k];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    volume[k] += a.dot(b.cross(c)) / 6;
    vector_area[k] += 0.5 * n;
    area[k] += 0.5 * n.norm();
  }
  std::vector<char> flipped(components, 0);
  for (size_t k = 0; k < components; ++k) {
    flipped[k] = volume[k] < 0 && area[k] > 0 &&
                 vector_area[k].norm() <= kMaxOpenness * area[k];
    if (flipped[k]) out.inside_out.push_back({first_vertex[k], 0, volume[k]});
  }
  std::vector<int> listed(components, -1);
  for (size_t k = 0, i = 0; k < components; ++k)
    if (flipped[k]) listed[k] = static_cast<int>(i++);
  for (int t = 0; t < triangle_count; ++t) {
    const int k = triangle_component[t];
    if (!flipped[k]) continue;
    out.triangle_sign[t] = -1;
    ++out.inside_out[listed[k]].triangle_count;
  }
  return out;
}

}  // namespace isk
