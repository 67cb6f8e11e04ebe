#include "isk/tracking/dislocation.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>

#include "isk/core/error.hpp"

namespace isk {

std::vector<DislocationCandidate> dislocationCandidates(
    const Rig& rig, const BonePartition& partition,
    const std::vector<int>& representative) {
  const Skeleton& skeleton = rig.skeleton;
  const SkinWeights& weights = rig.weights;
  const float floor = 0.01f * rig.boundingBoxDiagonal();
  const int vertex_count = rig.mesh.vertexCount();
  const TransformList binds = skeleton.bindGlobals();
  std::vector<DislocationCandidate> out;
  for (int v = 0; v < vertex_count; ++v) {
    if (representative[v] != v) continue;
    const int home = partition.vertex_joint[v];
    if (home < 0) continue;
    for (uint32_t i = weights.offsets[v]; i < weights.offsets[v + 1]; ++i) {
      const int other = static_cast<int>(weights.joints[i]);
      if (other == home || !(weights.weights[i] >= kDislocationMinWeight))
        continue;
      const bool linked = skeleton.joints[other].parent == home ||
                          skeleton.joints[home].parent == other;
      const Eigen::Vector3f rest = rig.mesh.positions.row(v).transpose();
      const float radius = std::max(
          floor, static_cast<float>(
                     partition.segments[home].distance(rest.cast<double>())));
      if (linked) {
        // A parent and its child turn about their shared joint: only a
        // vertex farther than the axis reach from it can be dislocated.
        const int child = skeleton.joints[other].parent == home ? other : home;
        if ((rest - binds[child].translation()).norm() <=
            kDislocationAxisReach * radius)
          continue;
      }
      DislocationCandidate c;
      c.vertex = v;
      c.home_joint = home;
      c.other_joint = other;
      c.rest = rest;
      c.radius = radius;
      out.push_back(c);
    }
  }
  return out;
}

std::vector<int> dislocatedVertices(
    const std::vector<DislocationCandidate>& candidates,
    const TransformList& skinning) {
  std::vector<int> out;
  const int joints = static_cast<int>(skinning.size());
  for (const DislocationCandidate& c : candidates) {
    if (c.home_joint < 0 || c.home_joint >= joints || c.other_joint < 0 ||
        c.other_joint >= joints)
      throw Error(ErrorCode::kInvalidArgument,
                  "dislocatedVertices: vertex " + std::to_string(c.vertex) +
                      " blends joints " + std::to_string(c.home_joint) +
                      " and " + std::to_string(c.other_joint) + " but " +
                      std::to_string(joints) + " transforms were given");
    if (!out.empty() && out.back() == c.vertex) continue;
    // The other joint's motion seen from the home joint's frame.
    const Eigen::Affine3f relative =
        skinning[c.home_joint].inverse() * skinning[c.other_joint];
    const float move = (relative * c.rest - c.rest).norm();
    if (!(move > kDislocationMinMove * c.radius)) continue;
    // A turn by angle a about an axis at distance d moves a point by
    // 2 sin(a / 2) d: d from the move (infinite for a slide).
    const float angle =
        Eigen::AngleAxisf(Eigen::Matrix3f(relative.linear())).angle();
    const float chord = 2.f * std::sin(0.5f * std::abs(angle));
    if (move > kDislocationAxisReach * c.radius * chord)
      out.push_back(c.vertex);
  }
  return out;
}

}  // namespace isk
