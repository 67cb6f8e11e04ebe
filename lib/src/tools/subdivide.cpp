#include "isk/tools/subdivide.hpp"

#include <string>
#include <unordered_map>

#include "isk/core/error.hpp"

namespace isk {
namespace {

Rig subdivideOnce(const Rig& rig) {
  const Mesh& in = rig.mesh;
  const int n = in.vertexCount();
  const int f = in.triangleCount();
  std::unordered_map<uint64_t, int> midpoint_of_edge;
  std::vector<std::pair<int, int>> new_edges;  // ends of each new vertex
  auto midpoint = [&](int a, int b) {
    const uint64_t key = (static_cast<uint64_t>(std::min(a, b)) << 32) |
                         static_cast<uint32_t>(std::max(a, b));
    auto [it, inserted] =
        midpoint_of_edge.emplace(key, n + static_cast<int>(new_edges.size()));
    if (inserted) new_edges.emplace_back(a, b);
    return it->second;
  };
  TriangleMatrix triangles(4 * f, 3);
  for (int t = 0; t < f; ++t) {
    const int a = in.triangles(t, 0), b = in.triangles(t, 1),
              c = in.triangles(t, 2);
    const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    triangles.row(4 * t) << a, ab, ca;
    triangles.row(4 * t + 1) << ab, b, bc;
    triangles.row(4 * t + 2) << ca, bc, c;
    triangles.row(4 * t + 3) << ab, bc, ca;
  }
  const int total = n + static_cast<int>(new_edges.size());
  Rig out;
  out.source = rig.source;
  out.skeleton = rig.skeleton;
  out.clips = rig.clips;
  out.warnings = rig.warnings;
  out.mesh.positions.resize(total, 3);
  out.mesh.normals.resize(total, 3);
  out.mesh.positions.topRows(n) = in.positions;
  out.mesh.normals.topRows(n) = in.normals;
  out.mesh.triangles = std::move(triangles);
  std::vector<std::vector<std::pair<int, float>>> lists(total);
  const SkinWeights& w = rig.weights;
  for (int v = 0; v < n; ++v) {
    for (uint32_t i = w.offsets[v]; i < w.offsets[v + 1]; ++i) {
      lists[v].emplace_back(w.joints[i], w.weights[i]);
    }
  }
  for (size_t e = 0; e < new_edges.size(); ++e) {
    const auto [a, b] = new_edges[e];
    const int v = n + static_cast<int>(e);
    out.mesh.positions.row(v) =
        0.5f * (in.positions.row(a) + in.positions.row(b));
    Eigen::RowVector3f normal = in.normals.row(a) + in.normals.row(b);
    out.mesh.normals.row(v) = normal.norm() > 0.f
                                  ? Eigen::RowVector3f(normal.normalized())
                                  : in.normals.row(a);
    for (int end : {a, b}) {
      for (uint32_t i = w.offsets[end]; i < w.offsets[end + 1]; ++i) {
        lists[v].emplace_back(w.joints[i], 0.5f * w.weights[i]);
      }
    }
  }
  out.weights = SkinWeights::fromLists(lists);
  out.weights.normalize();
  out.weights.sortByWeight();
  // Midpoints are appended after all original vertices, so the input parts'
  // ranges no longer hold: one part for the whole subdivided mesh.
  out.mesh.parts.push_back({"subdivided", 0, total, 0, 4 * f});
  return out;
}

}  // namespace

Rig subdivideRig(const Rig& rig, int levels) {
  if (levels < 0 || levels > 6) {
    throw Error(ErrorCode::kInvalidArgument,
                "subdivideRig: levels must be in 0..6 (got " +
                    std::to_string(levels) + ")");
  }
  Rig result = rig;
  for (int level = 0; level < levels; ++level) result = subdivideOnce(result);
  return result;
}

}  // namespace isk
