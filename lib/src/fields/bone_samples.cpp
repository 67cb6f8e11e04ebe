#include "isk/fields/bone_samples.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace isk {
namespace {

// splitmix64: portable and the same on every standard library (unlike the
// std distributions), so a rig always gets the same samples.
class Random {
 public:
  explicit Random(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  double uniform() { return (next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  uint64_t state_;
};

Eigen::Vector3d position(const Mesh& mesh, int v) {
  return mesh.positions.row(v).transpose().cast<double>();
}

}  // namespace

HermiteSamples BoneSamples::all() const {
  HermiteSamples s = surface;
  s.positions.insert(s.positions.end(), closure.positions.begin(),
                     closure.positions.end());
  s.normals.insert(s.normals.end(), closure.normals.begin(),
                   closure.normals.end());
  return s;
}

BoneSamples sampleBonePart(const Mesh& mesh, const BonePartition& partition,
                           int joint, const BoneSamplingOptions& options,
                           const SurfaceOrientation* orientation) {
  BoneSamples out;
  out.joint = joint;
  if (!partition.hasPart(joint)) return out;
  const std::vector<int>& triangles = partition.part_triangles[joint];
  const BoneSegment& segment = partition.segments[joint];

  // Geometric vertex normals (area-weighted), from the part's triangles: the
  // file's normals may be split or flat-shaded.
  std::vector<Eigen::Vector3d> vertex_normals(mesh.vertexCount(),
                                              Eigen::Vector3d::Zero());
  std::vector<double> cumulative_area;
  cumulative_area.reserve(triangles.size());
  double area = 0;
  for (int t : triangles) {
    const Eigen::Vector3d a = position(mesh, mesh.triangles(t, 0));
    const Eigen::Vector3d b = position(mesh, mesh.triangles(t, 1));
    const Eigen::Vector3d c = position(mesh, mesh.triangles(t, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a) *
                              (orientation ? orientation->triangle_sign[t] : 1);
    for (int i = 0; i < 3; ++i) vertex_normals[mesh.triangles(t, i)] += n;
    area += 0.5 * n.norm();
    cumulative_area.push_back(area);
  }
  if (!(area > 0) || options.target_samples <= 0) return out;

  const double radius = 0.75 * std::sqrt(area / options.target_samples);
  const int candidates = 40 * options.target_samples;
  const size_t most = static_cast<size_t>(kMaxSamplesPerTarget) *
                      static_cast<size_t>(options.target_samples);
  Random random(options.seed ^ (0x9e3779b97f4a7c15ull * (joint + 1)));
  std::vector<Eigen::Vector3d> kept;
  for (int i = 0; i < candidates && out.surface.positions.size() < most; ++i) {
    const double pick = random.uniform() * area;
    const size_t index = std::min<size_t>(
        std::lower_bound(cumulative_area.begin(), cumulative_area.end(), pick) -
            cumulative_area.begin(),
        triangles.size() - 1);
    const int t = triangles[index];
    double u = random.uniform(), v = random.uniform();
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const int ia = mesh.triangles(t, 0), ib = mesh.triangles(t, 1),
              ic = mesh.triangles(t, 2);
    const Eigen::Vector3d a = position(mesh, ia), b = position(mesh, ib),
                          c = position(mesh, ic);
    const Eigen::Vector3d p = a + u * (b - a) + v * (c - a);
    bool too_close = false;
    for (const auto& q : kept) {
      if ((q - p).squaredNorm() < radius * radius) {
        too_close = true;
        break;
      }
    }
    if (too_close) continue;
    kept.push_back(p);
    Eigen::Vector3d n = (1 - u - v) * vertex_normals[ia].normalized() +
                        u * vertex_normals[ib].normalized() +
                        v * vertex_normals[ic].normalized();
    if (!(n.norm() > 1e-9) || !n.allFinite())
      n = (b - a).cross(c - a) *
          (orientation ? orientation->triangle_sign[t] : 1);
    if (!segment.degenerate) {
      // Culling planes stand only at ends shared with another part: a free
      // end (a fingertip, the end of a tube) keeps the samples that close it.
      const double along = segment.along(p);
      if ((segment.close_start && !(along > options.culling_h)) ||
          (segment.close_end && !(along < 1 - options.culling_h))) {
        ++out.culled;
        continue;
      }
    }
    out.surface.positions.push_back(p);
    out.surface.normals.push_back(n.normalized());
  }

  if (options.closure_points && !segment.degenerate) {
    const Eigen::Vector3d dir = segment.direction();
    auto nearest = [&](const Eigen::Vector3d& joint_position) {
      double best = std::numeric_limits<double>::infinity();
      for (int v : partition.part_vertices[joint])
        if (partition.vertex_layer.empty() || !partition.vertex_layer[v])
          best = std::min(best, (position(mesh, v) - joint_position).norm());
      return best;
    };
    if (segment.close_start) {
      out.closure.positions.push_back(segment.start -
                                      nearest(segment.start) * dir);
      out.closure.normals.push_back(-dir);
    }
    if (segment.close_end) {
      out.closure.positions.push_back(segment.end + nearest(segment.end) * dir);
      out.closure.normals.push_back(dir);
    }
  }
  return out;
}

}  // namespace isk
