#include "isk/fields/bone_partition.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "isk/core/error.hpp"
#include "isk/core/one_ring.hpp"

namespace isk {

Eigen::Vector3d BoneSegment::direction() const {
  const Eigen::Vector3d d = end - start;
  const double n = d.norm();
  return n > 0 ? Eigen::Vector3d(d / n) : Eigen::Vector3d::UnitX();
}

double BoneSegment::along(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d d = end - start;
  const double l2 = d.squaredNorm();
  return l2 > 0 ? (p - start).dot(d) / l2 : 0.0;
}

double BoneSegment::distance(const Eigen::Vector3d& p) const {
  const double t = std::clamp(along(p), 0.0, 1.0);
  return (p - (start + t * (end - start))).norm();
}

namespace {

Eigen::Vector3d jointPosition(const TransformList& globals, int j) {
  return globals[j].translation().cast<double>();
}

double meanDistance(const BoneSegment& s, const Mesh& mesh,
                    const std::vector<int>& vertices) {
  double sum = 0;
  for (int v : vertices)
    sum += s.distance(mesh.positions.row(v).transpose().cast<double>());
  return vertices.empty() ? 0 : sum / vertices.size();
}

// A part that lies mostly off its bone (less than half of its span along
// the bone on it) and wraps a span of its own clearly better than the bone
// takes that span as its segment: its extent along the bone's line, or along
// the incoming bone's (parent joint -> joint) where that fits better. Some
// files weight each stretch of a smooth tube most to a joint at one end of
// it or beyond (animation_with_skeleton.fbx), and the bone's culling planes,
// closure points and radius would fit little of it. A part merely longer
// than its bone (an ear, a hip) wraps the bone about as well and keeps it.
constexpr double kPartSpanOverlap = 0.5;   // of the span, at most
constexpr double kPartSpanDistance = 0.7;  // of the mean distance to the bone

// The part's extent along the line through `line`'s ends; `overlap` its
// share within them.
BoneSegment partSpan(const Mesh& mesh, const std::vector<int>& part,
                     const BoneSegment& line, double* overlap) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int v : part) {
    const double t =
        line.along(mesh.positions.row(v).transpose().cast<double>());
    lo = std::min(lo, t);
    hi = std::max(hi, t);
  }
  *overlap =
      hi - lo > 0 ? (std::min(hi, 1.0) - std::max(lo, 0.0)) / (hi - lo) : 1.0;
  BoneSegment span = line;
  const Eigen::Vector3d b0 = line.start, d = line.end - line.start;
  span.start = b0 + lo * d;
  span.end = b0 + hi * d;
  return span;
}

void fitSegmentToPart(const Mesh& mesh, const std::vector<int>& part,
                      const Eigen::Vector3d* parent_position,
                      BoneSegment* segment) {
  BoneSegment& s = *segment;
  double overlap = 1;
  const BoneSegment along_bone = partSpan(mesh, part, s, &overlap);
  if (!(overlap < kPartSpanOverlap)) return;
  double best = kPartSpanDistance * meanDistance(s, mesh, part);
  const BoneSegment* chosen = nullptr;
  if (const double d = meanDistance(along_bone, mesh, part); d < best) {
    best = d;
    chosen = &along_bone;
  }
  BoneSegment incoming = s, along_incoming;
  if (parent_position) {
    incoming.start = *parent_position;
    incoming.end = s.start;
    if (incoming.length() > 0) {
      double on_incoming = 0;
      along_incoming = partSpan(mesh, part, incoming, &on_incoming);
      if (const double d = meanDistance(along_incoming, mesh, part);
          on_incoming >= kPartSpanOverlap && d < best)
        chosen = &along_incoming;
    }
  }
  if (chosen) {
    s.start = chosen->start;
    s.end = chosen->end;
  }
}

// Connected components of the mesh welded by position: #V component ids.
std::vector<int> weldedComponents(const Mesh& mesh) {
  const int vertex_count = mesh.vertexCount();
  std::vector<int> parent = weldedRepresentatives(mesh.positions);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int t = 0; t < mesh.triangleCount(); ++t)
    for (int k = 1; k < 3; ++k) {
      const int a = find(mesh.triangles(t, 0)), b = find(mesh.triangles(t, k));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  std::vector<int> component(vertex_count);
  for (int v = 0; v < vertex_count; ++v) component[v] = find(v);
  return component;
}

// One component's vertices in a part, and its span around the bone.
struct PartComponent {
  int id = -1;
  std::vector<int> vertices;
  double along_min = 0, along_max = 0, distance_max = 0, distance_mean = 0;
  int sectors = 0;  // of 8 around the bone, those holding a vertex
};

// Whether 90% of c's vertices lie in s's envelope (see the header).
bool inEnvelope(const PartComponent& c, const PartComponent& s,
                const BoneSegment& segment, const Mesh& mesh) {
  const double grow = 0.1 * (s.along_max - s.along_min);
  int inside = 0;
  for (int v : c.vertices) {
    const Eigen::Vector3d p = mesh.positions.row(v).transpose().cast<double>();
    const double a = segment.along(p);
    inside += a >= s.along_min - grow && a <= s.along_max + grow &&
              segment.distance(p) <= 1.25 * s.distance_max;
  }
  return inside >= 0.9 * static_cast<double>(c.vertices.size());
}

// Moves the layers' triangles of every part to layer_triangles and flags
// their vertices (see the header).
void findLayers(const Mesh& mesh, BonePartition& partition) {
  const int joint_count = static_cast<int>(partition.part_vertices.size());
  partition.layer_triangles.assign(joint_count, {});
  partition.vertex_layer.assign(mesh.vertexCount(), 0);
  std::vector<int> component;
  for (int j = 0; j < joint_count; ++j) {
    const BoneSegment& segment = partition.segments[j];
    if (segment.degenerate || partition.part_vertices[j].empty()) continue;
    if (component.empty()) component = weldedComponents(mesh);
    std::vector<PartComponent> parts;
    for (int v : partition.part_vertices[j]) {
      auto it = std::find_if(parts.begin(), parts.end(), [&](const auto& c) {
        return c.id == component[v];
      });
      if (it == parts.end()) {
        parts.push_back({});
        it = parts.end() - 1;
        it->id = component[v];
      }
      it->vertices.push_back(v);
    }
    if (parts.size() < 2) continue;
    const Eigen::Vector3d axis = segment.direction();
    const Eigen::Vector3d u = axis.unitOrthogonal(), w = axis.cross(u);
    for (PartComponent& c : parts) {
      c.along_min = std::numeric_limits<double>::infinity();
      c.along_max = -c.along_min;
      unsigned sectors = 0;
      for (int v : c.vertices) {
        const Eigen::Vector3d p =
            mesh.positions.row(v).transpose().cast<double>();
        const double a = segment.along(p), d = segment.distance(p);
        c.along_min = std::min(c.along_min, a);
        c.along_max = std::max(c.along_max, a);
        c.distance_max = std::max(c.distance_max, d);
        c.distance_mean += d / c.vertices.size();
        const Eigen::Vector3d r = p - segment.start;
        const double angle = std::atan2(r.dot(w), r.dot(u));  // [-pi, pi]
        sectors |= 1u << std::clamp(
                       static_cast<int>((angle + M_PI) / (2 * M_PI) * 8), 0, 7);
      }
      for (; sectors; sectors &= sectors - 1) ++c.sectors;
    }
    // A layer wraps the bone as the skin under it does, and lies in the
    // skin's envelope, farther out.
    auto wraps = [](const PartComponent& c) { return c.sectors >= 7; };
    std::vector<uint8_t> layer(parts.size(), 0);
    for (size_t c = 0; c < parts.size(); ++c)
      for (size_t s = 0; s < parts.size() && !layer[c]; ++s)
        layer[c] = s != c && wraps(parts[c]) && wraps(parts[s]) &&
                   parts[s].distance_mean < parts[c].distance_mean &&
                   inEnvelope(parts[c], parts[s], segment, mesh);
    if (std::all_of(layer.begin(), layer.end(), [](uint8_t l) { return l; }))
      continue;  // no skin to follow: fit them all
    std::vector<int> skin;
    for (int t : partition.part_triangles[j]) {
      bool in_layer = false;
      for (size_t c = 0; c < parts.size(); ++c)
        in_layer |= layer[c] && parts[c].id == component[mesh.triangles(t, 0)];
      (in_layer ? partition.layer_triangles[j] : skin).push_back(t);
    }
    partition.part_triangles[j] = std::move(skin);
    for (size_t c = 0; c < parts.size(); ++c)
      if (layer[c])
        for (int v : parts[c].vertices) partition.vertex_layer[v] = 1;
  }
}

}  // namespace

BonePartition partitionMesh(const Rig& rig) {
  rig.validate().throwIfFailed("partitionMesh");
  const Skeleton& skeleton = rig.skeleton;
  const Mesh& mesh = rig.mesh;
  const int joint_count = skeleton.jointCount();
  const int vertex_count = mesh.vertexCount();
  const TransformList globals = skeleton.bindGlobals();
  const double min_length = 1e-6 * std::max(rig.boundingBoxDiagonal(), 1e-30f);

  std::vector<std::vector<int>> children(joint_count);
  for (int j = 0; j < joint_count; ++j)
    if (skeleton.joints[j].parent >= 0)
      children[skeleton.joints[j].parent].push_back(j);

  BonePartition partition;
  partition.part_vertices.assign(joint_count, {});
  partition.part_triangles.assign(joint_count, {});
  partition.segments.resize(joint_count);

  // Provisional segments (joint -> first non-coincident child) break weight
  // ties; final segments are chosen once the parts are known.
  std::vector<BoneSegment> provisional(joint_count);
  for (int j = 0; j < joint_count; ++j) {
    provisional[j].joint = j;
    provisional[j].start = provisional[j].end = jointPosition(globals, j);
    for (int c : children[j]) {
      const Eigen::Vector3d p = jointPosition(globals, c);
      if ((p - provisional[j].start).norm() > min_length) {
        provisional[j].end = p;
        break;
      }
    }
  }

  partition.vertex_joint.assign(vertex_count, -1);
  const SkinWeights& w = rig.weights;
  for (int v = 0; v < vertex_count; ++v) {
    const Eigen::Vector3d p = mesh.positions.row(v).transpose().cast<double>();
    int best = w.joints[w.offsets[v]];
    const float best_weight = w.weights[w.offsets[v]];
    double best_distance = provisional[best].distance(p);
    for (uint32_t i = w.offsets[v] + 1; i < w.offsets[v + 1]; ++i) {
      if (best_weight - w.weights[i] > 1e-6f) break;  // sorted by weight
      const int j = w.joints[i];
      const double d = provisional[j].distance(p);
      if (d < best_distance) {
        best = j;
        best_distance = d;
      }
    }
    partition.vertex_joint[v] = best;
    partition.part_vertices[best].push_back(v);
  }
  for (int t = 0; t < mesh.triangleCount(); ++t) {
    const int a = partition.vertex_joint[mesh.triangles(t, 0)];
    const int b = partition.vertex_joint[mesh.triangles(t, 1)];
    const int c = partition.vertex_joint[mesh.triangles(t, 2)];
    const int owner = (b == c) ? b : a;
    partition.part_triangles[owner].push_back(t);
  }

  for (int j = 0; j < joint_count; ++j) {
    BoneSegment& s = partition.segments[j];
    s.joint = j;
    s.start = s.end = jointPosition(globals, j);
    const std::vector<int>& part = partition.part_vertices[j];
    // Several children: the one that continues the parent's direction (the
    // spine goes on to the neck, not to a shoulder); at a root, the one
    // nearest on average to the part's vertices.
    const int parent_joint = skeleton.joints[j].parent;
    Eigen::Vector3d incoming = Eigen::Vector3d::Zero();
    if (parent_joint >= 0)
      incoming = s.start - jointPosition(globals, parent_joint);
    const bool follow_chain = incoming.norm() > min_length;
    double best_fit = std::numeric_limits<double>::infinity();
    for (int c : children[j]) {
      BoneSegment candidate = s;
      candidate.end = jointPosition(globals, c);
      candidate.end_joint = c;
      if (candidate.length() <= min_length) continue;
      const double fit = follow_chain
                             ? -candidate.direction().dot(incoming.normalized())
                             : meanDistance(candidate, mesh, part);
      if (fit < best_fit) {
        best_fit = fit;
        s.end = candidate.end;
        s.end_joint = c;
      }
    }
    if (s.end_joint < 0 && !part.empty()) {
      // A leaf: continue the parent's direction as far as the part reaches.
      const int parent = skeleton.joints[j].parent;
      if (parent >= 0) {
        const Eigen::Vector3d from = jointPosition(globals, parent);
        const Eigen::Vector3d dir = s.start - from;
        if (dir.norm() > min_length) {
          const Eigen::Vector3d unit = dir.normalized();
          double reach = 0;
          for (int v : part)
            reach = std::max(
                reach,
                (mesh.positions.row(v).transpose().cast<double>() - s.start)
                    .dot(unit));
          if (reach > min_length) s.end = s.start + reach * unit;
        }
      }
    }
    if (!part.empty() && s.length() > min_length) {
      // The incoming bone is a candidate where the parent's part goes on
      // into this one.
      const bool parent_part =
          parent_joint >= 0 && !partition.part_vertices[parent_joint].empty();
      const Eigen::Vector3d parent_position =
          parent_part ? jointPosition(globals, parent_joint)
                      : Eigen::Vector3d::Zero();
      fitSegmentToPart(mesh, part, parent_part ? &parent_position : nullptr,
                       &s);
    }
    s.degenerate = s.length() <= min_length;
    if (s.degenerate) s.end = s.start;
    const int parent = skeleton.joints[j].parent;
    s.close_start = !s.degenerate && parent >= 0 &&
                    !partition.part_vertices[parent].empty();
    s.close_end = !s.degenerate && s.end_joint >= 0 &&
                  !partition.part_vertices[s.end_joint].empty();
  }

  findLayers(mesh, partition);

  for (int j = 0; j < joint_count; ++j) {
    const Joint& joint = skeleton.joints[j];
    if (partition.part_vertices[j].empty()) {
      if (joint.is_skin_joint)
        partition.warnings.push_back(
            "joint '" + joint.name +
            "' has no vertex of its own (no vertex has it as its largest "
            "weight): it gets no field");
      continue;
    }
    partition.field_joints.push_back(j);
    if (partition.segments[j].degenerate)
      partition.warnings.push_back(
          "joint '" + joint.name +
          "' has a zero-length bone (no child or part extent to point to): "
          "its field is fitted around a point, without culling planes or "
          "closure points");
  }
  return partition;
}

}  // namespace isk
