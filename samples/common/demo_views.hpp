// The demo's comparison pictures, all but the drawing: the most bent frame
// of a clip, the views that look at its fold (compare.png and closeup.png),
// the contact vertices' colours and the pictures' texts. Host only.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "demo_tables.hpp"
#include "isk/core/types.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/rig.hpp"
#include "isk/rig/skeleton.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "mesh_render.hpp"

namespace isk::samples::demo {

// Contact vertices in the implicit panels (red is taken by skin seen from
// inside).
constexpr Rgb kContactColour = {20, 210, 40};
// closeup.png shows this fraction of compare.png's half height around the
// most bent joint.
constexpr float kCloseUpFraction = 0.4f;

// The pose of a rig's pictures: the frame where a joint is bent the most.
struct BentFrame {
  int frame = 0;
  int joint = -1;  // -1: no joint with a skinned parent (frame 0 then)
  double degrees = 0;
  Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();           // bend axis, posed
  Eigen::Vector3f joint_position = Eigen::Vector3f::Zero();  // posed
  Eigen::Vector3f parent_position = Eigen::Vector3f::Zero();  // posed
  // Posed position of the joint's first child; unset for a leaf joint.
  std::optional<Eigen::Vector3f> child_position;
};

// The most bent frame of `times`: the one with the largest rotation of a
// skin joint relative to its parent bone, measured from the bind pose (the
// angle of R_parent^T R_joint, the rotations of their skinning transforms).
// That is the bend a person sees at an elbow or a knee, whatever the whole
// character does (walks, turns), and it gives the title's angle and the
// axis to look along. For the procedural bend clips it is the last frame
// (every joint at the clip's full angle); ties go to the earlier frame and
// the joint nearer the root (the arm's elbow). Joints count when they and
// their parent carry skin (all joints when the rig flags none).
BentFrame mostBentFrame(const Skeleton& skeleton, const AnimationClip& clip,
                        const std::vector<double>& times);

// The two views of the comparison pictures.
struct ComparisonViews {
  RenderView whole;          // compare.png: every mesh
  RenderView close;          // closeup.png: around the fold
  std::string close_legend;  // how closeup.png looks at it
};

// Looks along the bend axis of the most bent joint (the fold seen in
// profile, as at an elbow seen from the side) from the side away from the
// rest of the body, the rest mesh's longest side upwards (a standing
// character upright), framing the three methods' meshes `positions` (DQS
// second) at one scale. The close-up centres on the fold, turned towards its
// inside.
ComparisonViews comparisonViews(const Rig& rig, const BentFrame& bent,
                                const Matrix3Xf (&positions)[kMethodCount]);

// The pictures table's row of the most bent frame at `time`: its joint and
// bend, each method's self-intersections (seam copies grouped by
// `vertex_groups`) and the implicit pose's contact vertices (`states`).
PictureRow describePictures(const std::string& rig_name, const Rig& rig,
                            const BentFrame& bent, double time,
                            const Matrix3Xf (&positions)[kMethodCount],
                            const std::vector<TrackState>& states,
                            const std::vector<int>& vertex_groups);

// Per-vertex colours of the implicit panel: kContactColour at the contact
// vertices, the front colour elsewhere.
std::vector<Rgb> contactColours(int vertex_count,
                                const std::vector<TrackState>& states);

// The panels' captions: method, self-intersections, contacts (implicit).
std::vector<std::string> methodCaptions(const PictureRow& row);
// "<rig>, frame F of 0-N (t = T s): <joint> bent D deg"
std::string pictureTitle(const PictureRow& row, const BentFrame& bent,
                         int frame_count);

}  // namespace isk::samples::demo
