#include "isk/core/one_ring.hpp"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <sstream>
#include <unordered_map>

#include "isk/core/error.hpp"

namespace isk {

namespace {

using ConnectivityMesh = OpenMesh::TriMesh_ArrayKernelT<>;

struct PositionKey {
  uint32_t bits[3];
  bool operator==(const PositionKey& o) const {
    return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
  }
};
struct PositionHash {
  size_t operator()(const PositionKey& k) const {
    uint64_t h = 1469598103934665603ull;
    for (uint32_t b : k.bits) h = (h ^ b) * 1099511628211ull;
    return static_cast<size_t>(h);
  }
};

PositionKey keyOf(const Matrix3Xf& positions, int v) {
  PositionKey key;
  for (int c = 0; c < 3; ++c) {
    float x = positions(v, c);
    if (x == 0.f) x = 0.f;  // -0 and +0 are one spot
    std::memcpy(&key.bits[c], &x, sizeof(float));
  }
  return key;
}

// OpenMesh reports refused faces (complex edges and vertices) on omerr; we
// count them ourselves, so keep the log quiet while building.
std::mutex& omerrMutex() {
  static std::mutex mutex;
  return mutex;
}

}  // namespace

const char* ringKindName(RingKind kind) {
  switch (kind) {
    case RingKind::kClosed:
      return "closed";
    case RingKind::kBoundary:
      return "boundary";
    case RingKind::kIrregular:
      return "irregular";
    case RingKind::kIsolated:
      return "isolated";
    case RingKind::kDuplicate:
      return "duplicate";
  }
  return "?";
}

int OneRings::count(RingKind kind) const {
  return static_cast<int>(std::count(kinds.begin(), kinds.end(), kind));
}

std::vector<int> weldedRepresentatives(const Matrix3Xf& positions) {
  const int vertex_count = static_cast<int>(positions.rows());
  std::vector<int> representative(vertex_count);
  std::unordered_map<PositionKey, int, PositionHash> first;
  first.reserve(vertex_count * 2);
  for (int v = 0; v < vertex_count; ++v)
    representative[v] = first.emplace(keyOf(positions, v), v).first->second;
  return representative;
}

OneRings OneRings::build(const Matrix3Xf& positions,
                         const TriangleMatrix& triangles) {
  const int vertex_count = static_cast<int>(positions.rows());
  OneRings rings;
  rings.representative = weldedRepresentatives(positions);
  for (Eigen::Index t = 0; t < triangles.rows(); ++t)
    for (int c = 0; c < 3; ++c)
      if (triangles(t, c) < 0 || triangles(t, c) >= vertex_count)
        throw Error(ErrorCode::kInvalidArgument,
                    "one-rings: triangle " + std::to_string(t) +
                        " refers to vertex " + std::to_string(triangles(t, c)) +
                        " but the mesh has " + std::to_string(vertex_count));

  // Connectivity of the welded mesh: one OpenMesh vertex per representative.
  ConnectivityMesh mesh;
  std::vector<ConnectivityMesh::VertexHandle> handle(vertex_count);
  std::vector<int> vertex_of;  // OpenMesh index -> our representative
  for (int v = 0; v < vertex_count; ++v) {
    if (rings.representative[v] != v) continue;
    handle[v] = mesh.add_vertex(ConnectivityMesh::Point(
        positions(v, 0), positions(v, 1), positions(v, 2)));
    vertex_of.push_back(v);
  }
  std::vector<char> irregular(vertex_count, 0);
  std::vector<std::vector<int>> refused_neighbours;  // per irregular vertex
  std::vector<int> refused;                          // welded triangles
  {
    std::lock_guard<std::mutex> lock(omerrMutex());
    omerr().disable();
    for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
      const int a = rings.representative[triangles(t, 0)];
      const int b = rings.representative[triangles(t, 1)];
      const int c = rings.representative[triangles(t, 2)];
      if (a == b || b == c || a == c) continue;  // degenerate once welded
      const auto face = mesh.add_face(handle[a], handle[b], handle[c]);
      if (!face.is_valid()) {
        refused.insert(refused.end(), {a, b, c});
        irregular[a] = irregular[b] = irregular[c] = 1;
      }
    }
    omerr().enable();
  }
  // Irregular vertices take every neighbour of every triangle they are in.
  std::unordered_map<int, std::vector<int>> irregular_rings;
  if (!refused.empty()) {
    for (Eigen::Index t = 0; t < triangles.rows(); ++t) {
      int r[3];
      for (int c = 0; c < 3; ++c) r[c] = rings.representative[triangles(t, c)];
      if (r[0] == r[1] || r[1] == r[2] || r[0] == r[2]) continue;
      for (int c = 0; c < 3; ++c) {
        if (!irregular[r[c]]) continue;
        auto& list = irregular_rings[r[c]];
        list.push_back(r[(c + 1) % 3]);
        list.push_back(r[(c + 2) % 3]);
      }
    }
    for (auto& entry : irregular_rings) {
      std::sort(entry.second.begin(), entry.second.end());
      entry.second.erase(std::unique(entry.second.begin(), entry.second.end()),
                         entry.second.end());
    }
  }

  rings.kinds.resize(vertex_count);
  rings.offsets.assign(vertex_count + 1, 0);
  for (int v = 0; v < vertex_count; ++v) {
    rings.offsets[v] = static_cast<uint32_t>(rings.neighbours.size());
    if (rings.representative[v] != v) {
      rings.kinds[v] = RingKind::kDuplicate;
      continue;
    }
    if (irregular[v]) {
      rings.kinds[v] = RingKind::kIrregular;
      const auto& list = irregular_rings[v];
      rings.neighbours.insert(rings.neighbours.end(), list.begin(), list.end());
      if (list.empty()) rings.kinds[v] = RingKind::kIsolated;
      continue;
    }
    const auto vh = handle[v];
    if (mesh.is_isolated(vh)) {
      rings.kinds[v] = RingKind::kIsolated;
      continue;
    }
    rings.kinds[v] =
        mesh.is_boundary(vh) ? RingKind::kBoundary : RingKind::kClosed;
    for (auto it = mesh.cvv_ccwiter(vh); it.is_valid(); ++it)
      rings.neighbours.push_back(vertex_of[it->idx()]);
  }
  rings.offsets[vertex_count] = static_cast<uint32_t>(rings.neighbours.size());
  return rings;
}

const char* relaxationRuleName(RelaxationRule rule) {
  switch (rule) {
    case RelaxationRule::kMeanValue:
      return "mean value";
    case RelaxationRule::kClampedMean:
      return "clamped";
    case RelaxationRule::kUniform:
      return "uniform";
    case RelaxationRule::kFixed:
      return "fixed";
  }
  return "?";
}

int RelaxationWeights::count(RelaxationRule rule) const {
  return static_cast<int>(std::count(rules.begin(), rules.end(), rule));
}

std::string RelaxationWeights::describe() const {
  std::ostringstream out;
  out << count(RelaxationRule::kMeanValue) << " mean value, "
      << count(RelaxationRule::kClampedMean) << " clamped, "
      << count(RelaxationRule::kUniform) << " uniform, "
      << count(RelaxationRule::kFixed) << " fixed";
  return out.str();
}

RelaxationWeights RelaxationWeights::build(const OneRings& rings,
                                           const Matrix3Xf& rest_positions) {
  const int vertex_count = rings.vertexCount();
  RelaxationWeights out;
  out.weights.assign(rings.neighbours.size(), 0.f);
  out.rules.assign(vertex_count, RelaxationRule::kFixed);
  std::vector<Eigen::Vector3d> edges;
  std::vector<double> angles, weights;
  for (int v = 0; v < vertex_count; ++v) {
    const RingKind kind = rings.kinds[v];
    const uint32_t begin = rings.offsets[v], end = rings.offsets[v + 1];
    const int n = static_cast<int>(end - begin);
    if (kind != RingKind::kClosed && kind != RingKind::kIrregular) continue;
    if (n == 0) continue;
    auto uniform = [&] {
      for (uint32_t i = begin; i < end; ++i) out.weights[i] = 1.f / n;
      out.rules[v] = RelaxationRule::kUniform;
    };
    if (kind == RingKind::kIrregular || n < 3) {
      uniform();
      continue;
    }
    const Eigen::Vector3d centre = rest_positions.row(v).cast<double>();
    edges.resize(n);
    for (int j = 0; j < n; ++j)
      edges[j] = rest_positions.row(rings.neighbours[begin + j])
                     .cast<double>()
                     .transpose() -
                 centre;
    // The ring's area-weighted normal defines the tangent plane.
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    for (int j = 0; j < n; ++j) normal += edges[j].cross(edges[(j + 1) % n]);
    if (!(normal.norm() > 0)) {
      uniform();
      continue;
    }
    normal.normalize();
    for (auto& e : edges) e -= e.dot(normal) * normal;
    angles.resize(n);
    bool usable = true;
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector3d& a = edges[j];
      const Eigen::Vector3d& b = edges[(j + 1) % n];
      angles[j] = std::atan2(a.cross(b).dot(normal), a.dot(b));
      if (!(a.norm() > 0) || std::abs(angles[j]) >= M_PI - 1e-9) usable = false;
    }
    if (!usable) {
      uniform();
      continue;
    }
    weights.resize(n);
    double sum = 0;
    bool negative = false;
    for (int j = 0; j < n; ++j) {
      const double before = angles[(j + n - 1) % n];
      weights[j] =
          (std::tan(before / 2) + std::tan(angles[j] / 2)) / edges[j].norm();
      if (weights[j] < 0) {
        negative = true;
        weights[j] = 0;
      }
      sum += weights[j];
    }
    if (!(sum > 0) || !std::isfinite(sum)) {
      uniform();
      continue;
    }
    for (int j = 0; j < n; ++j)
      out.weights[begin + j] = static_cast<float>(weights[j] / sum);
    out.rules[v] =
        negative ? RelaxationRule::kClampedMean : RelaxationRule::kMeanValue;
  }
  return out;
}

}  // namespace isk
