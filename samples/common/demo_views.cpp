#include "demo_views.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "field_pictures.hpp"
#include "isk/tools/self_intersection.hpp"

namespace isk::samples::demo {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The axis of the longest side of the bounding box of `positions` (a
// standing character's height, a limb's length).
Eigen::Vector3f longestAxis(const Matrix3Xf& positions) {
  const Eigen::Vector3f extent =
      (positions.colwise().maxCoeff() - positions.colwise().minCoeff())
          .transpose();
  Eigen::Index axis = 0;
  extent.maxCoeff(&axis);
  return Eigen::Vector3f::Unit(axis);
}

// About the radius of the limb around joint j at the bind pose: the median
// distance from the joint to its 16 nearest rest vertices.
float limbRadius(const Rig& rig, int j) {
  const Eigen::Vector3f joint =
      rig.skeleton.joints[j].inverse_bind.inverse().translation();
  std::vector<float> distances(rig.mesh.vertexCount());
  for (int v = 0; v < rig.mesh.vertexCount(); ++v) {
    distances[v] = (rig.mesh.positions.row(v).transpose() - joint).norm();
  }
  const size_t k = std::min<size_t>(16, distances.size());
  if (k == 0) return 0;
  std::partial_sort(distances.begin(), distances.begin() + k, distances.end());
  return distances[k / 2];
}

// Where `skinning` puts the origin of joint j (its bind-pose position).
Eigen::Vector3f posedJoint(const Skeleton& skeleton,
                           const TransformList& skinning, int j) {
  return skinning[j] * skeleton.joints[j].inverse_bind.inverse().translation();
}

// The whole picture's camera: along the bend axis, from the side of the
// joint away from the body's centre (the near leg of a walking character);
// upwards the rest mesh's longest side, turned towards the parent bone.
struct Camera {
  Eigen::Vector3f direction;
  Eigen::Vector3f up;
  Eigen::Vector3f inner = Eigen::Vector3f::Zero();  // into the fold
};

Camera bendCamera(const Rig& rig, const BentFrame& bent,
                  const Matrix3Xf& dqs_positions) {
  Camera camera{bent.axis, longestAxis(rig.mesh.positions)};
  Eigen::Vector3f& direction = camera.direction;
  Eigen::Vector3f& up = camera.up;
  if (bent.joint >= 0) {
    const Eigen::Vector3f centroid = dqs_positions.colwise().mean().transpose();
    if (direction.dot(bent.joint_position - centroid) <
        -1e-3f * rig.boundingBoxDiagonal()) {
      direction = -direction;
    }
    const Eigen::Vector3f parent = bent.parent_position - bent.joint_position;
    if (up.dot(parent) < 0) up = -up;
    if (up.cross(direction).norm() < 0.1f) up = parent;
    if (bent.child_position) {
      const Eigen::Vector3f child = *bent.child_position - bent.joint_position;
      if (parent.norm() > 0 && child.norm() > 0) {
        camera.inner = parent.normalized() + child.normalized();
      }
    }
  }
  if (up.cross(direction).norm() < 1e-3f * up.norm()) {
    up = direction.unitOrthogonal();
  }
  return camera;
}

// Centres `close` on the fold, which lies between the joint and the crease
// where the two bones' skins meet, on the bisector of the bones about
// r / sin(half the angle between them) from the joint (r the limb's
// radius), and turns it towards the inside of the fold, so the skins that
// meet there show (their contact vertices too), not only their profile.
void aimAtFold(const Rig& rig, const BentFrame& bent, const Camera& camera,
               RenderView& close, std::string& legend) {
  close.target = bent.joint_position;
  const Eigen::Vector3f& inner = camera.inner;
  if (!(inner.norm() > 1e-3f)) return;
  const float r = limbRadius(rig, bent.joint);
  const double half_angle = (180.0 - bent.degrees) / 2 * kPi / 180;
  const float crease = std::min(
      3 * r, static_cast<float>(r / std::max(std::sin(half_angle), 1e-3)));
  close.target += 0.5f * crease * inner.normalized();
  close.half_height = std::max(close.half_height, 0.5f * crease + r);
  const Eigen::Vector3f& direction = camera.direction;
  const Eigen::Vector3f towards_fold = inner - inner.dot(direction) * direction;
  if (towards_fold.norm() > 1e-3f * inner.norm()) {
    const double tilt = kCloseUpTiltDegrees * kPi / 180;
    close.direction =
        (static_cast<float>(std::cos(tilt)) * direction +
         static_cast<float>(std::sin(tilt)) * towards_fold.normalized())
            .normalized();
    legend = "seen " + formatNumber("%.0f", kCloseUpTiltDegrees) +
             " deg off the bend axis, from inside the fold";
  }
}

}  // namespace

BentFrame mostBentFrame(const Skeleton& skeleton, const AnimationClip& clip,
                        const std::vector<double>& times) {
  const bool flags = skeleton.skinJointCount() > 0;
  auto carriesSkin = [&](int j) {
    return !flags || skeleton.joints[j].is_skin_joint;
  };
  BentFrame best;
  best.degrees = -1;
  for (size_t f = 0; f < times.size(); ++f) {
    const TransformList skinning = clipSkinning(skeleton, clip, times[f]);
    for (int j = 0; j < skeleton.jointCount(); ++j) {
      const int p = skeleton.joints[j].parent;
      if (p < 0 || !carriesSkin(j) || !carriesSkin(p)) continue;
      const Eigen::Matrix3f parent = skinning[p].rotation();
      const Eigen::AngleAxisf bend(
          Eigen::Matrix3f(parent.transpose() * skinning[j].rotation()));
      const double degrees = bend.angle() * 180.0 / kPi;
      if (!(degrees > best.degrees + 1e-3)) continue;
      best.frame = static_cast<int>(f);
      best.joint = j;
      best.degrees = degrees;
      best.axis = (parent * bend.axis()).normalized();
      best.joint_position = posedJoint(skeleton, skinning, j);
      best.parent_position = posedJoint(skeleton, skinning, p);
      best.child_position.reset();
      for (int c = j + 1; c < skeleton.jointCount(); ++c) {
        if (skeleton.joints[c].parent != j) continue;
        best.child_position = posedJoint(skeleton, skinning, c);
        break;
      }
    }
  }
  if (best.joint < 0) best = BentFrame{};
  return best;
}

ComparisonViews comparisonViews(const Rig& rig, const BentFrame& bent,
                                const Matrix3Xf (&positions)[kMethodCount]) {
  const Camera camera = bendCamera(rig, bent, positions[1]);
  ComparisonViews views;
  views.whole = frameViews({&positions[0], &positions[1], &positions[2]},
                           camera.direction, camera.up, 0.08f);
  views.close = views.whole;
  views.close_legend = "seen along the bend axis";
  views.close.half_height = views.whole.half_height * kCloseUpFraction;
  if (bent.joint >= 0) {
    aimAtFold(rig, bent, camera, views.close, views.close_legend);
  }
  return views;
}

PictureRow describePictures(const std::string& rig_name, const Rig& rig,
                            const BentFrame& bent, double time,
                            const Matrix3Xf (&positions)[kMethodCount],
                            const std::vector<TrackState>& states,
                            const std::vector<int>& vertex_groups) {
  PictureRow row;
  row.rig = rig_name;
  row.frame = bent.frame;
  row.time = time;
  row.degrees = bent.joint >= 0 ? bent.degrees : 0;
  if (bent.joint >= 0) row.joint = rig.skeleton.joints[bent.joint].name;
  for (int m = 0; m < kMethodCount; ++m) {
    row.intersections[m] = countSelfIntersections(
        positions[m], rig.mesh.triangles, &vertex_groups);
  }
  const size_t vertices = static_cast<size_t>(rig.mesh.vertexCount());
  for (size_t v = 0; v < states.size() && v < vertices; ++v) {
    if (states[v] == TrackState::kContact) ++row.contacts;
  }
  return row;
}

std::vector<Rgb> contactColours(int vertex_count,
                                const std::vector<TrackState>& states) {
  std::vector<Rgb> colours(vertex_count, RenderStyle{}.front);
  for (size_t v = 0; v < states.size() && v < colours.size(); ++v) {
    if (states[v] == TrackState::kContact) colours[v] = kContactColour;
  }
  return colours;
}

std::vector<std::string> methodCaptions(const PictureRow& row) {
  std::vector<std::string> captions;
  for (int m = 0; m < kMethodCount; ++m) {
    std::string caption = std::string(kMethods[m].caption) + "\n" +
                          std::to_string(row.intersections[m]) +
                          " self-intersections";
    if (kMethods[m].implicit) {
      caption +=
          "\n" + std::to_string(row.contacts) + " contact vertices (green)";
    }
    captions.push_back(caption);
  }
  return captions;
}

std::string pictureTitle(const PictureRow& row, const BentFrame& bent,
                         int frame_count) {
  std::string title = row.rig + ", frame " + std::to_string(bent.frame) +
                      " of 0-" + std::to_string(frame_count - 1) +
                      " (t = " + formatNumber("%.2f", row.time) + " s)";
  if (bent.joint >= 0) {
    title += ": " + row.joint + " bent " + formatNumber("%.0f", bent.degrees) +
             " deg";
  }
  return title;
}

}  // namespace isk::samples::demo
