// Dislocation guard (not in the paper; docs/algorithm.md): the vertices
// whose skinning blends two joints that move apart as no joint between them
// could, kept on geometric skinning for the frame.
//
// Each bone's field follows its joint rigidly (section 4.1), so the
// composed field can only stand for a pose where the bones that share a
// vertex turn about a joint near it. Weights that blend a vertex between
// joints the skeleton does not link -- two chains under one skin (several
// root joints), siblings -- can ask for more, and so can weights that spread
// a parent and its child over a stretch longer than the axis reach from
// their joint (a tube blended smoothly over many short bones): when the two
// joints' relative
// motion at the vertex's rest position is a turn about an axis far away, or
// a slide, the two fields are dislocated against each other and the march
// pulls the skin apart to follow them (a tube bent in the middle crumples
// and gains volume where its two chains meet). There geometric skinning is
// the only consistent surface.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "isk/fields/bone_partition.hpp"
#include "isk/rig/rig.hpp"

namespace isk {

// A vertex weighted to a joint other than its own part's joint (its home
// joint): an unlinked one, or its parent or a child where the vertex lies
// more than kDislocationAxisReach radii from their shared joint (nearer, a
// turn about that joint cannot dislocate it).
struct DislocationCandidate {
  int vertex = -1;       // a representative of the welded mesh
  int home_joint = -1;   // the joint of the vertex's part (skeleton index)
  int other_joint = -1;  // the unlinked joint (skeleton index)
  Eigen::Vector3f rest = Eigen::Vector3f::Zero();  // rest position
  float radius = 0;  // distance from the home bone at rest (model units)
};

// Joints below this weight at a vertex are not candidates.
constexpr float kDislocationMinWeight = 0.15f;
// A pose dislocates a candidate when the relative motion of its two joints
// moves its rest position by more than kDislocationMinMove radii, about an
// axis more than kDislocationAxisReach radii from it (or along one: a slide).
constexpr float kDislocationMinMove = 0.1f;
constexpr float kDislocationAxisReach = 3.f;

// The candidates of `rig` (validated) with `partition` (of the same rig):
// every representative vertex (`representative`, #V, of the welded mesh)
// and every joint of weight >= kDislocationMinWeight at it other than its
// home joint; the home joint's parent or child only where the vertex lies
// more than kDislocationAxisReach radii from the joint they share (the
// child's bind position). The radius is floored at 1% of the rig's
// bounding-box diagonal. Sorted by vertex.
std::vector<DislocationCandidate> dislocationCandidates(
    const Rig& rig, const BonePartition& partition,
    const std::vector<int>& representative);

// The vertices among `candidates` that `skinning` (one transform per joint
// of the candidates' skeleton, rest -> posed) dislocates, each once, in the
// candidates' order. Throws isk::Error(kInvalidArgument) when a candidate's
// joint has no transform.
std::vector<int> dislocatedVertices(
    const std::vector<DislocationCandidate>& candidates,
    const TransformList& skinning);

}  // namespace isk
