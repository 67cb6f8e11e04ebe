// Mesh partition into one part per bone, and the bone segments the implicit
// fields are built around (Vaillant et al. 2013, section 4.1 "Problem
// setting"; DESIGN.md section 3 "Partition").
//
// Each vertex goes to the joint with its largest weight; a tie (weights
// within 1e-6) goes to the joint whose bone segment is nearest. A joint that
// receives no vertex gets no part and no field; the partition reports it.
//
// The bone of joint j runs from the joint's bind position b0 to b1:
// - one child: that child's bind position;
// - several children: the child that best continues the direction from the
//   parent (the chain goes on: spine to neck rather than to a shoulder, hand
//   to middle finger); at a root, the child whose segment is nearest on
//   average to the part's vertices (the bone the part wraps around);
// - no child (or only children at b0): along the direction from the parent,
//   as far as the part's vertices reach along it;
// - none of these possible (a root without children, or all candidate
//   segments shorter than 1e-6 of the mesh diagonal): a point bone, b1 = b0,
//   `degenerate` set; its field is fitted without culling planes or closure
//   points, and a warning says so.
// A part that lies along that segment's line but mostly beyond its ends
// (less than half of its span along the bone within [b0, b1]), and whose
// vertices are on average nearer its own span than the bone by a factor of
// 0.7 or more, takes its span instead: b0 and b1 move along the line to
// the part's first and last vertex (smooth tubes whose stretches are
// weighted most to a joint at one end, animation_with_skeleton.fbx).
//
// Layers (our addition, docs/algorithm.md): clothes, eyes and other
// accessory meshes share the bones of the skin under them, and a field
// fitted to two nested surfaces fits neither. Within a part, the mesh's
// connected components (welded by position) are compared: a component C is
// a layer of another, S, when both wrap the bone (their vertices lie in 7
// or more of 8 sectors around it), C lies farther from the bone on average,
// and 90% of C's vertices of the part are in S's envelope: within S's span
// along the bone (grown by 10% of it at each end) and within 1.25 times S's
// largest distance from the bone (a sleeve around an arm, trousers around a
// leg; not eyes or teeth, which do not wrap the bone). A layer's triangles
// are not sampled (layer_triangles instead of part_triangles) and its
// vertices are flagged: they keep their rest iso value in the skin's field
// and follow it as an offset surface.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "isk/rig/rig.hpp"

namespace isk {

// A bone as the fields see it: a segment in model space at the bind pose
// (model units).
struct BoneSegment {
  int joint = -1;  // joint index in the skeleton
  // b0: the joint (or the start of its part's span, above), bind pose,
  // model space.
  Eigen::Vector3d start = {0, 0, 0};
  Eigen::Vector3d end = {0, 0, 0};  // b1
  int end_joint = -1;               // the child joint at b1, -1 if none
  bool degenerate = false;          // b1 == b0 (see above)
  // Whether the end touches another part (the parent's part at b0, the
  // child's part at b1): only those ends get a culling plane and a closure
  // point.
  bool close_start = false;
  bool close_end = false;

  double length() const { return (end - start).norm(); }
  // Unit direction b0 -> b1 (x axis when degenerate).
  Eigen::Vector3d direction() const;
  // Distance from p to the segment.
  double distance(const Eigen::Vector3d& p) const;
  // Position of p along the bone: 0 at b0, 1 at b1 (eq. 2's ratio); 0 when
  // degenerate.
  double along(const Eigen::Vector3d& p) const;
};

// The mesh split into one part per joint; indices are the rig's vertex,
// triangle and joint indices.
struct BonePartition {
  std::vector<int> vertex_joint;  // #V: the joint each vertex belongs to
  // Per joint (#joints): the part's vertices and triangles (a triangle
  // belongs to the part holding two or three of its vertices, else to its
  // first vertex's part), and the bone segment. Empty parts: no field.
  std::vector<std::vector<int>> part_vertices;
  std::vector<std::vector<int>> part_triangles;
  // Per joint: the part's triangles in layers (see above), not sampled;
  // part_triangles holds the others.
  std::vector<std::vector<int>> layer_triangles;
  // #V: 1 where the vertex is in a layer of its part (see above).
  std::vector<uint8_t> vertex_layer;
  std::vector<BoneSegment> segments;
  // Joints with a part, in joint order: one field each.
  std::vector<int> field_joints;
  // One sentence per skin joint without vertices or degenerate bone.
  std::vector<std::string> warnings;

  // True when `joint` is a skeleton index whose part has vertices.
  bool hasPart(int joint) const {
    return joint >= 0 && joint < static_cast<int>(part_vertices.size()) &&
           !part_vertices[joint].empty();
  }
};

// Partitions `rig` (validated first: isk::Error kInvalidArgument naming what
// is wrong).
BonePartition partitionMesh(const Rig& rig);

}  // namespace isk
