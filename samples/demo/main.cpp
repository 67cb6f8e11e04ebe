// isk-demo: skins the procedural "arm" and "cylinder" rigs (the cylinder
// also bent to 135 degrees, where its two halves press against each other)
// and CesiumMan from the data folder (its first clip; skipped, with a note,
// when the file is missing) with LBS, DQS and implicit skinning, on the
// default OpenCL device and on the CPU reference. Writes the OpenCL frames
// under out/<rig>/<method>/ and a summary table (stdout and out/summary.md):
// per rig and method the volume ratio range, self-intersections, contact
// vertices, milliseconds per frame and the OpenCL-vs-reference agreement.
// At each rig's most bent frame it draws the three methods side by side
// (out/<rig>/compare.png, and closeup.png around the most bent joint), the
// implicit panel's contact vertices tinted. Then evaluates each rig's
// implicit fields at the skinned vertices on the OpenCL device and on the
// CPU reference (bind pose and the clip's middle frame), draws the composed
// field at both poses (out/<rig>/fields/composed.png, composed_bent.png) and
// adds a table on the fields. Last, draws the composition operators
// (out/operators/, as isk-operator-plots does: iso-curves in the (f1, f2)
// plane and the arm bent at the elbow, Figure 5(c)) and adds their tables.
// Needs no input file.
#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "field_pictures.hpp"
#include "isk/rig/animation.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/core/error.hpp"
#include "isk/io/export.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/rig/pose.hpp"
#include "isk/io/rig_params.hpp"
#include "isk/tools/self_intersection.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "mesh_render.hpp"
#include "operator_plots.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

constexpr double kPi = 3.14159265358979323846;

// OpenCL and reference outputs of LBS and DQS agree to float rounding; this
// bound (relative to the bounding-box diagonal) only flags real
// disagreements.
constexpr double kAgreementTolerance = 1e-4;
// Implicit skinning stops each vertex on threshold tests (converged, contact
// angle) that float rounding can flip between the devices; a flipped stop
// moves a vertex by up to a projection step (at most
// SurfaceTrackingOptions::max_step = 0.02 of the diagonal). This bound, half
// such a step, still flags a real disagreement (a stage missing or wrong on
// one device); PoCL agrees with the reference to ~5e-5.
constexpr double kImplicitAgreementTolerance = 1e-2;

// Largest |OpenCL - reference| field value accepted: both storages
// interpolate in the kernel, so both match to float rounding (GPUs may fuse
// multiply-adds).
constexpr double kFieldTolerance[] = {/*buffer*/ 1e-4, /*image*/ 1e-4};

// Frames per clip by default: the clip sampled uniformly, at most this many
// (30 per second plus one for the 1 s bends of the procedural rigs; fewer
// than 30 per second for longer clips, so the demo stays quick).
constexpr int kDefaultMaxFrames = 31;

// Longer side of the field pictures, in pixels.
constexpr int kPictureSize = 512;
// Side of each operator panel and bend picture: smaller than
// isk-operator-plots' default to keep the demo quick.
constexpr int kOperatorPictureSize = 256;
// Side of each (square) panel of compare.png and closeup.png.
constexpr int kPanelSize = 400;
// closeup.png shows this fraction of compare.png's half height around the
// most bent joint.
constexpr float kCloseUpFraction = 0.4f;
// closeup.png looks this far off the bend axis, towards the inside of the
// fold.
constexpr double kCloseUpTiltDegrees = 35;
// Contact vertices in the implicit panels (red is taken by skin seen from
// inside).
constexpr isk::samples::Rgb kContactColour = {20, 210, 40};

// The three methods, in the order of the table and of the panels.
struct MethodSpec {
  const char* name;     // table and folder name
  const char* caption;  // panel caption
  bool implicit;
  isk::SkinningMethod method;  // geometric skinning (implicit: its base)
};
const MethodSpec kMethods[] = {
    {"lbs", "LBS", false, isk::SkinningMethod::kLinearBlend},
    {"dqs", "DQS", false, isk::SkinningMethod::kDualQuaternion},
    {"implicit", "implicit", true, isk::SkinningMethod::kDualQuaternion}};
constexpr int kMethodCount = 3;

// A rig of the demo.
struct RigJob {
  std::string name;    // in the tables, and the output folder
  std::string source;  // loadRig input: builtin:NAME or a file
  // > 0: the clip is a bend of every joint to this angle over 1 s instead
  // of the rig's first clip.
  double bend_degrees = 0;
  // Fields shared with the rig of this name (same mesh and skeleton): no
  // second build and no second row in the fields table.
  std::string fields_of;
};

struct Row {
  std::string rig;
  std::string clip;
  std::string method;
  std::string device;
  int frames = 0;
  double median_ms = 0;
  std::optional<double> reference_ms;  // with an OpenCL device
  std::optional<double> volume_min, volume_max;
  int intersections_max = 0;
  long long intersections_total = 0;
  std::optional<double> contact_median;  // implicit only
  std::optional<double> max_difference;  // with an OpenCL device
};

std::string formatNumber(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

std::string optionalNumber(const char* format,
                           const std::optional<double>& value,
                           const char* absent) {
  return value ? formatNumber(format, *value) : absent;
}

std::string formatTable(const std::vector<Row>& rows) {
  std::ostringstream out;
  out << "| rig | clip | method | device | frames | ms/frame (median) | "
         "volume ratio min | volume ratio max | self-intersections max per "
         "frame | self-intersections total | contact vertices (median) | "
         "reference ms/frame (median) | max abs(opencl - reference) / "
         "diagonal |\n"
      << "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const Row& row : rows) {
    out << "| " << row.rig << " | " << row.clip << " | " << row.method << " | "
        << row.device << " | " << row.frames << " | "
        << formatNumber("%.3f", row.median_ms) << " | "
        << optionalNumber("%.4f", row.volume_min, "n/a") << " | "
        << optionalNumber("%.4f", row.volume_max, "n/a") << " | "
        << row.intersections_max << " | " << row.intersections_total << " | "
        << optionalNumber("%.0f", row.contact_median, "-") << " | "
        << optionalNumber("%.3f", row.reference_ms, "-") << " | "
        << optionalNumber("%.2e", row.max_difference, "-") << " |\n";
  }
  return out.str();
}

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

// The axis of the longest side of the bounding box of `positions` (a
// standing character's height, a limb's length).
Eigen::Vector3f longestAxis(const isk::Matrix3Xf& positions) {
  const Eigen::Vector3f extent =
      (positions.colwise().maxCoeff() - positions.colwise().minCoeff())
          .transpose();
  Eigen::Index axis = 0;
  extent.maxCoeff(&axis);
  return Eigen::Vector3f::Unit(axis);
}

// About the radius of the limb around joint j at the bind pose: the median
// distance from the joint to its 16 nearest rest vertices.
float limbRadius(const isk::Rig& rig, int j) {
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
Eigen::Vector3f posedJoint(const isk::Skeleton& skeleton,
                           const isk::TransformList& skinning, int j) {
  return skinning[j] * skeleton.joints[j].inverse_bind.inverse().translation();
}

// The most bent frame of `times`: the one with the largest rotation of a
// skin joint relative to its parent bone, measured from the bind pose (the
// angle of R_parent^T R_joint, the rotations of their skinning transforms).
// That is the bend a person sees at an elbow or a knee, whatever the whole
// character does (walks, turns), and it gives the title's angle and the
// axis to look along. For the procedural bend clips it is the last frame
// (every joint at the clip's full angle); ties go to the earlier frame and
// the joint nearer the root (the arm's elbow). Joints count when they and
// their parent carry skin (all joints when the rig flags none).
BentFrame mostBentFrame(const isk::Skeleton& skeleton,
                        const isk::AnimationClip& clip,
                        const std::vector<double>& times) {
  const bool flags = skeleton.skinJointCount() > 0;
  auto carriesSkin = [&](int j) {
    return !flags || skeleton.joints[j].is_skin_joint;
  };
  BentFrame best;
  best.degrees = -1;
  for (size_t f = 0; f < times.size(); ++f) {
    const isk::TransformList skinning =
        isk::samples::clipSkinning(skeleton, clip, times[f]);
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

// What the pictures of one rig show, for the summary's pictures table.
struct PictureRow {
  std::string rig;
  int frame = 0;
  double time = 0;
  std::string joint = "-";
  double degrees = 0;
  int intersections[kMethodCount] = {};
  int contacts = 0;
  std::vector<std::string> pictures;  // relative to the output folder
};

std::string formatPictureTable(const std::vector<PictureRow>& rows) {
  std::ostringstream out;
  out << "| rig | frame | time (s) | most bent joint | bend (deg) | LBS "
         "self-intersections | DQS self-intersections | implicit "
         "self-intersections | implicit contact vertices | pictures |\n"
      << "|---|---:|---:|---|---:|---:|---:|---:|---:|---|\n";
  for (const PictureRow& row : rows) {
    std::string pictures;
    for (const std::string& p : row.pictures) {
      pictures += (pictures.empty() ? "" : ", ") + p;
    }
    out << "| " << row.rig << " | " << row.frame << " | "
        << formatNumber("%.3f", row.time) << " | " << row.joint << " | "
        << formatNumber("%.1f", row.degrees) << " | " << row.intersections[0]
        << " | " << row.intersections[1] << " | " << row.intersections[2]
        << " | " << row.contacts << " | " << pictures << " |\n";
  }
  return out.str();
}

// Implicit skinning of one pose again, on the device of `opencl` (the CPU
// reference when null), for what the frame loop does not hand out: the
// tracking states (contact vertices) and the welded vertex groups. Each
// frame starts afresh from the base skinning, so the positions are those of
// the frame loop at the same pose.
struct ImplicitPose {
  isk::Matrix3Xf positions;
  std::vector<isk::TrackState> states;
  std::vector<int> vertex_groups;  // seam copies share a group
};

ImplicitPose skinImplicitPose(
    FrameSkinner* opencl, const isk::Rig& rig,
    const std::shared_ptr<const isk::ImplicitFields>& fields,
    const isk::ImplicitSkinnerOptions& options,
    const isk::TransformList& skinning) {
  ImplicitPose pose;
  if (opencl) {
    isk::ImplicitSkinner skinner(opencl->sharedContext(), rig, fields, options);
    skinner.run(skinning);
    skinner.readPositions(pose.positions);
    skinner.tracking().readStates(pose.states);
    pose.vertex_groups = skinner.trackingMesh().rings.representative;
  } else {
    isk::CpuImplicitSkinner skinner(rig, fields, options);
    skinner.run(skinning);
    pose.positions = skinner.positions();
    pose.states = skinner.tracking().states();
    pose.vertex_groups = skinner.trackingMesh().rings.representative;
  }
  return pose;
}

// Draws the three methods' meshes at the most bent frame side by side, same
// view and scale, looking along the bend axis of the most bent joint (the
// fold seen in profile, as at an elbow seen from the side) from the side
// away from the rest of the body, the rest mesh's longest side upwards (a
// standing character upright); the implicit panel's contact vertices
// tinted. Writes out_dir/<rig>/compare.png (the
// whole meshes) and closeup.png (around the joint's fold, turned towards its
// inside) and returns the table row.
PictureRow writeComparePictures(const std::string& rig_name,
                                const isk::Rig& rig, const BentFrame& bent,
                                double time, int frame_count,
                                const isk::Matrix3Xf (&positions)[kMethodCount],
                                const ImplicitPose& implicit_pose,
                                const std::string& out_dir) {
  namespace s = isk::samples;
  PictureRow row;
  row.rig = rig_name;
  row.frame = bent.frame;
  row.time = time;
  row.degrees = bent.joint >= 0 ? bent.degrees : 0;
  if (bent.joint >= 0) row.joint = rig.skeleton.joints[bent.joint].name;
  for (int m = 0; m < kMethodCount; ++m) {
    row.intersections[m] = isk::countSelfIntersections(
        positions[m], rig.mesh.triangles, &implicit_pose.vertex_groups);
  }
  std::vector<s::Rgb> colours(rig.mesh.vertexCount(), s::RenderStyle{}.front);
  for (size_t v = 0; v < implicit_pose.states.size() && v < colours.size();
       ++v) {
    if (implicit_pose.states[v] == isk::TrackState::kContact) {
      colours[v] = kContactColour;
      ++row.contacts;
    }
  }

  // The view: along the bend axis, from the side of the joint away from
  // the body's centre (the near leg of a walking character); upwards the
  // rest mesh's longest side, turned towards the parent bone.
  Eigen::Vector3f direction = bent.axis;
  Eigen::Vector3f up = longestAxis(rig.mesh.positions);
  Eigen::Vector3f inner = Eigen::Vector3f::Zero();  // into the fold
  if (bent.joint >= 0) {
    const Eigen::Vector3f centroid =
        positions[1].colwise().mean().transpose();  // DQS
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
        inner = parent.normalized() + child.normalized();
      }
    }
  }
  if (up.cross(direction).norm() < 1e-3f * up.norm()) {
    up = direction.unitOrthogonal();
  }
  const s::RenderView whole = s::frameViews(
      {&positions[0], &positions[1], &positions[2]}, direction, up, 0.08f);
  // The close-up: around the fold, which lies between the joint and the
  // crease where the two bones' skins meet, on the bisector of the bones
  // about r / sin(half the angle between them) from the joint (r the
  // limb's radius).
  s::RenderView close = whole;
  std::string close_legend = "seen along the bend axis";
  close.half_height = whole.half_height * kCloseUpFraction;
  if (bent.joint >= 0) {
    close.target = bent.joint_position;
    if (inner.norm() > 1e-3f) {
      const float r = limbRadius(rig, bent.joint);
      const double half_angle = (180.0 - bent.degrees) / 2 * kPi / 180;
      const float crease = std::min(
          3 * r, static_cast<float>(r / std::max(std::sin(half_angle), 1e-3)));
      close.target += 0.5f * crease * inner.normalized();
      close.half_height = std::max(close.half_height, 0.5f * crease + r);
      // Turned towards the inside of the fold, so the skins that meet
      // there show (their contact vertices too), not only their profile.
      const Eigen::Vector3f towards_fold =
          inner - inner.dot(direction) * direction;
      if (towards_fold.norm() > 1e-3f * inner.norm()) {
        const double tilt = kCloseUpTiltDegrees * kPi / 180;
        close.direction =
            (static_cast<float>(std::cos(tilt)) * direction +
             static_cast<float>(std::sin(tilt)) * towards_fold.normalized())
                .normalized();
        close_legend = "seen " + formatNumber("%.0f", kCloseUpTiltDegrees) +
                       " deg off the bend axis, from inside the fold";
      }
    }
  }

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
  std::string title = rig_name + ", frame " + std::to_string(bent.frame) +
                      " of 0-" + std::to_string(frame_count - 1) +
                      " (t = " + formatNumber("%.2f", time) + " s)";
  if (bent.joint >= 0) {
    title += ": " + row.joint + " bent " + formatNumber("%.0f", bent.degrees) +
             " deg";
  }
  const std::string legend =
      "\ngreen: contact vertices, red: skin seen from inside (pushed through "
      "skin)";

  const fs::path rig_dir = fs::path(out_dir) / rig_name;
  fs::create_directories(rig_dir);
  const struct {
    const char* file;
    const s::RenderView& view;
    std::string suffix;
  } pictures[] = {{"compare.png", whole,
                   bent.joint >= 0 ? "\nseen along the bend axis" : ""},
                  {"closeup.png", close, ", close-up\n" + close_legend}};
  for (const auto& picture : pictures) {
    std::vector<s::Image> panels;
    for (int m = 0; m < kMethodCount; ++m) {
      s::RenderStyle style;
      if (kMethods[m].implicit) style.vertex_colours = &colours;
      panels.push_back(s::renderMesh(positions[m], rig.mesh.triangles,
                                     picture.view, kPanelSize, kPanelSize,
                                     style));
    }
    s::writePng(
        (rig_dir / picture.file).string(),
        s::sideBySide(panels, captions, title + picture.suffix + legend));
    row.pictures.push_back((fs::path(rig_name) / picture.file).string());
  }
  return row;
}

// One rig's implicit fields: how they were built, how far the vertices' iso
// values are from the surface's 0.5, how OpenCL agrees with the reference.
struct FieldRow {
  std::string rig;
  int fields = 0;
  int samples_min = 0, samples_max = 0;  // fitted points per field
  double fit_bake_ms = 0;                // the cache read when `cached`
  bool cached = false;                   // fields loaded from the field cache
  double mib = 0;
  double iso_mean = 0, iso_max = 0;  // |iso value - 0.5| over the vertices
  std::string storage = "n/a";       // OpenCL storage, n/a without OpenCL
  std::optional<double> max_difference;
  std::vector<std::string> pictures;  // relative to the output folder
};

std::string formatFieldTable(const std::vector<FieldRow>& rows) {
  std::ostringstream out;
  out << "| rig | fields | samples per field | fit+bake ms (cached: load "
         "ms) | field MiB | "
         "mean abs(iso - 0.5) | max abs(iso - 0.5) | OpenCL storage | max "
         "abs(opencl - reference) field value | pictures |\n"
      << "|---|---:|---:|---:|---:|---:|---:|---|---:|---|\n";
  for (const FieldRow& row : rows) {
    std::string pictures;
    for (const std::string& p : row.pictures) {
      pictures += (pictures.empty() ? "" : ", ") + p;
    }
    out << "| " << row.rig << " | " << row.fields << " | " << row.samples_min
        << "-" << row.samples_max << " | "
        << formatNumber("%.1f", row.fit_bake_ms) << " | "
        << formatNumber("%.2f", row.mib) << " | "
        << formatNumber("%.4f", row.iso_mean) << " | "
        << formatNumber("%.4f", row.iso_max) << " | " << row.storage << " | "
        << (row.max_difference ? formatNumber("%.2e", *row.max_difference)
                               : "-")
        << " | " << pictures << " |\n";
  }
  std::string cached;
  for (const FieldRow& row : rows)
    if (row.cached) cached += (cached.empty() ? "" : ", ") + row.rig;
  if (!cached.empty())
    out << "\nFields loaded from the field cache (ISK_CACHE_DIR; off "
           "disables it), fit+bake column gives the load: "
        << cached << "\n";
  return out.str();
}

// Describes the `fields` built for `rig` (fit+bake times measured by
// the build), compares OpenCL (when `context` is set) with the reference at
// the skinned vertices of the bind pose and of the clip at `bent_time`, and
// draws both poses under out_dir/<rig>/fields/.
FieldRow runFields(const std::string& rig_name, const isk::Rig& rig,
                   const isk::ImplicitFields& fields,
                   const isk::AnimationClip& clip, double bent_time,
                   const std::shared_ptr<isk::ClContext>& context,
                   const std::string& out_dir) {
  const std::string prefix = "isk-demo: " + rig_name + ": ";

  FieldRow row;
  row.rig = rig_name;
  row.fields = fields.grids.fieldCount();
  for (size_t i = 0; i < fields.samples.size(); ++i) {
    const int count =
        fields.samples[i].surface.size() + fields.samples[i].closure.size();
    row.samples_min = i == 0 ? count : std::min(row.samples_min, count);
    row.samples_max = i == 0 ? count : std::max(row.samples_max, count);
  }
  // Loaded from the cache: nothing was fitted or baked; the read's time.
  row.cached = fields.cache_origin == isk::FieldCacheOrigin::kLoaded;
  row.fit_bake_ms = row.cached
                        ? fields.times.sampling_ms
                        : fields.times.fitting_ms + fields.times.baking_ms;
  row.mib = fields.grids.bytes() / (1024.0 * 1024.0);
  for (const float iso : fields.iso_values) {
    const double off = std::abs(iso - 0.5);
    row.iso_mean += off;
    row.iso_max = std::max(row.iso_max, off);
  }
  if (!fields.iso_values.empty()) row.iso_mean /= fields.iso_values.size();

  // Bind pose: the rest mesh; bent: the clip's middle frame, skinned with
  // DQS like the pictures of isk-field-slices.
  const isk::TransformList bind = isk::bindPoseSkinning(rig.skeleton);
  const isk::TransformList bent =
      isk::samples::clipSkinning(rig.skeleton, clip, bent_time);
  const isk::Matrix3Xf bent_positions = isk::samples::dqsPositions(rig, bent);
  struct Pose {
    const char* picture;
    const isk::TransformList& skinning;
    const isk::Matrix3Xf& positions;
  };
  const Pose poses[] = {{"composed.png", bind, rig.mesh.positions},
                        {"composed_bent.png", bent, bent_positions}};

  std::unique_ptr<isk::ClFieldEvaluation> evaluation;
  if (context && row.fields > 0) {
    evaluation = std::make_unique<isk::ClFieldEvaluation>(
        context, fields.grids, rig.skeleton.jointCount(),
        isk::FieldStorage::kAuto, &fields.composition);
    row.storage = isk::fieldStorageName(evaluation->storage());
    row.max_difference = 0.0;
  }
  const fs::path fields_dir = fs::path(out_dir) / rig_name / "fields";
  fs::create_directories(fields_dir);
  for (const Pose& pose : poses) {
    if (evaluation) {
      const isk::Matrix4Xf reference = isk::evaluateComposedField(
          fields.grids, pose.skinning, pose.positions, &fields.composition);
      isk::Matrix4Xf opencl;
      evaluation->evaluate(pose.skinning, pose.positions, opencl);
      row.max_difference = std::max<double>(
          *row.max_difference,
          (opencl.col(0) - reference.col(0)).cwiseAbs().maxCoeff());
    }
    if (row.fields > 0) {
      isk::samples::writeComposedPicture((fields_dir / pose.picture).string(),
                                         rig, fields, pose.skinning,
                                         pose.positions, kPictureSize);
      row.pictures.push_back(
          (fs::path(rig_name) / "fields" / pose.picture).string());
    }
  }
  std::cerr << prefix << row.fields << " fields, pictures in "
            << fields_dir.string() << "\n";
  return row;
}

Row makeRow(const std::string& rig, const isk::AnimationClip& clip,
            const MethodSpec& method, const std::string& device,
            const RunResult& result) {
  Row row;
  row.rig = rig;
  row.clip = clip.name + " (" + formatNumber("%.2f", clip.duration) + " s)";
  row.method = method.name;
  row.device = device;
  row.frames = result.frames;
  row.median_ms = result.frame.median;
  row.volume_min = result.volume_ratio_min;
  row.volume_max = result.volume_ratio_max;
  for (const int count : result.self_intersections) {
    row.intersections_max = std::max(row.intersections_max, count);
    row.intersections_total += count;
  }
  if (method.implicit) {
    row.contact_median =
        isk::samples::summarize(
            std::vector<double>(result.contact_vertices.begin(),
                                result.contact_vertices.end()))
            .median;
  }
  return row;
}

// Everything the demo measures and draws, rig by rig.
class Demo {
 public:
  Demo(std::string out_dir, int frames, std::string device)
      : out_dir_(std::move(out_dir)),
        frames_(frames),
        device_(std::move(device)) {}

  void runRig(const RigJob& job);
  // Says on stderr and in the summary that `rig` was skipped and why.
  void skip(const std::string& rig, const std::string& why) {
    const std::string note = rig + " skipped: " + why;
    std::cerr << "isk-demo: " << note << "\n";
    notes_.push_back(note);
  }
  int finish();

 private:
  std::string out_dir_;
  int frames_;
  std::string device_;
  std::vector<Row> rows_;
  std::vector<FieldRow> field_rows_;
  std::vector<PictureRow> picture_rows_;
  std::vector<std::string> notes_;
  std::vector<std::string> frame_counts_;  // "rig: N of M"
  bool all_agree_ = true;
  bool implicit_agree_ = true;
  bool fields_agree_ = true;
  // One OpenCL context for the field evaluations, made with the first rig
  // that has an OpenCL device.
  std::shared_ptr<isk::ClContext> field_context_;
  std::map<std::string, std::shared_ptr<const isk::ImplicitFields>> fields_;
};

void Demo::runRig(const RigJob& job) {
  const std::string& rig_name = job.name;
  const std::string prefix = "isk-demo: " + rig_name + ": ";
  const isk::Rig rig =
      isk::samples::loadRig(job.source, isk::samples::guardedImportOptions());
  for (const std::string& warning : rig.warnings) {
    std::cerr << prefix << "warning: " << warning << "\n";
  }
  std::string clip_note;
  isk::AnimationClip clip = isk::samples::selectClip(rig, "", &clip_note);
  if (!clip_note.empty()) std::cerr << prefix << clip_note << "\n";
  if (job.bend_degrees > 0) {
    clip = isk::makeBendClip(
        rig.skeleton, static_cast<float>(job.bend_degrees * kPi / 180), 1.0);
    clip.name = "bend-" + formatNumber("%.0f", job.bend_degrees);
  }
  const int full_count = isk::samples::defaultFrameCount(clip);
  const int frame_count =
      frames_ > 0 ? frames_ : std::min(full_count, kDefaultMaxFrames);
  frame_counts_.push_back(rig_name + " " + std::to_string(frame_count) +
                          " of the " + std::to_string(full_count) +
                          " at 30 per second");
  const std::vector<double> times = isk::samples::frameTimes(clip, frame_count);
  const double diagonal = rig.boundingBoxDiagonal();
  const BentFrame bent = mostBentFrame(rig.skeleton, clip, times);

  std::shared_ptr<const isk::ImplicitFields> fields;
  if (const auto it = fields_.find(job.fields_of); it != fields_.end()) {
    fields = it->second;
  } else {
    // Cached on disk (ISK_CACHE_DIR; "off" disables it); an asset's
    // <asset>.isk.json parameters are used when present.
    isk::ImplicitFieldsOptions field_options;
    field_options.cache = true;
    const std::string params_path = isk::rigParamsPathFor(job.source);
    std::error_code ec;
    if (job.source.rfind("builtin:", 0) != 0 &&
        fs::is_regular_file(params_path, ec)) {
      isk::applyRigParams(isk::loadRigParams(params_path, &rig.skeleton),
                          &field_options);
      std::cerr << prefix << "parameters from " << params_path << "\n";
    }
    fields = std::make_shared<const isk::ImplicitFields>(
        isk::samples::buildFieldsWithProgress(rig, field_options,
                                              prefix + "building fields",
                                              prefix + "warning: "));
    fields_[rig_name] = fields;
    if (fields->cache_origin == isk::FieldCacheOrigin::kLoaded)
      std::cerr << prefix << "fields loaded from the cache "
                << fields->cache_file << "\n";
    else if (fields->cache_origin == isk::FieldCacheOrigin::kRebuilt)
      std::cerr << prefix << "fields rebuilt (" << fields->cache_note << ")\n";
  }
  // The paper's tracking, started from DQS, on the fields just built (with
  // the default options, which ImplicitSkinnerOptions::fields holds too).
  const isk::ImplicitSkinnerOptions implicit_options;

  FrameSkinner reference(rig, "reference");
  reference.enableImplicit(rig, fields, implicit_options);
  std::unique_ptr<FrameSkinner> opencl;
  try {
    opencl = std::make_unique<FrameSkinner>(rig, device_);
  } catch (const isk::Error& error) {
    if (error.code() != isk::ErrorCode::kNoDevice) throw;
    std::cerr << "isk-demo: no OpenCL device (" << error.what()
              << "); writing the CPU reference frames only\n";
  }
  if (opencl) opencl->enableImplicit(rig, fields, implicit_options);
  std::cerr << prefix << rig.mesh.vertexCount() << " vertices, " << times.size()
            << " frames of clip '" << clip.name << "'; pictures at frame "
            << bent.frame;
  if (bent.joint >= 0) {
    std::cerr << " (" << rig.skeleton.joints[bent.joint].name << " bent "
              << formatNumber("%.1f", bent.degrees) << " deg)";
  }
  std::cerr << "\n";

  isk::Matrix3Xf bent_positions[kMethodCount];
  // The written frames of each method (OpenCL's when there is a device),
  // played side by side in out/<rig>/animation.glb.
  std::vector<isk::GltfTrack> tracks(kMethodCount);
  for (int m = 0; m < kMethodCount; ++m) {
    const MethodSpec& method = kMethods[m];
    const std::string frames_dir =
        (fs::path(out_dir_) / rig_name / method.name).string();
    isk::samples::prepareOutputFolder(frames_dir, /*overwrite=*/true, "");

    // The reference keeps its frames so the OpenCL run can be compared
    // with them frame by frame. Self-intersections are counted on the
    // frames written (OpenCL's when there is a device).
    std::vector<isk::Matrix3Xf> reference_frames;
    isk::samples::RunOptions options;
    options.method = method.method;
    options.implicit = method.implicit;
    options.times = times;
    options.self_intersections = !opencl;
    options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                           const isk::Matrix3Xf& normals) {
      reference_frames.push_back(positions);
      if (frame == bent.frame) bent_positions[m] = positions;
      if (!opencl) {
        tracks[m].positions.push_back(positions);
        tracks[m].normals.push_back(normals);
      }
    };
    if (!opencl) options.out_dir = frames_dir;
    const RunResult reference_result =
        isk::samples::runFrames(rig, clip, reference, options);
    if (!opencl) {
      rows_.push_back(
          makeRow(rig_name, clip, method, "reference (CPU)", reference_result));
      continue;
    }

    double max_difference = 0;
    options.out_dir = frames_dir;
    options.self_intersections = true;
    options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                           const isk::Matrix3Xf& normals) {
      const double distance =
          isk::maxVertexDistance(positions, reference_frames[frame]);
      max_difference = std::max(max_difference, distance / diagonal);
      if (frame == bent.frame) bent_positions[m] = positions;
      tracks[m].positions.push_back(positions);
      tracks[m].normals.push_back(normals);
    };
    const RunResult opencl_result =
        isk::samples::runFrames(rig, clip, *opencl, options);
    Row row =
        makeRow(rig_name, clip, method, opencl->describe(), opencl_result);
    row.reference_ms = reference_result.frame.median;
    row.max_difference = max_difference;
    rows_.push_back(row);
    const double tolerance =
        method.implicit ? kImplicitAgreementTolerance : kAgreementTolerance;
    if (!(max_difference <= tolerance)) {
      (method.implicit ? implicit_agree_ : all_agree_) = false;
      std::cerr << prefix << method.name
                << ": OpenCL and the CPU reference differ by "
                << formatNumber("%.2e", max_difference)
                << " of the bounding-box diagonal (tolerance "
                << formatNumber("%.0e", tolerance) << ")\n";
    }
    std::cerr << prefix << method.name << ": "
              << formatNumber("%.3f", opencl_result.frame.median)
              << " ms/frame on OpenCL, "
              << formatNumber("%.3f", reference_result.frame.median)
              << " on the reference\n";
  }

  // LBS, DQS and implicit side by side, 1.2 bounding-box widths apart.
  {
    std::vector<isk::Matrix3Xf> all_frames;
    for (const isk::GltfTrack& track : tracks)
      all_frames.insert(all_frames.end(), track.positions.begin(),
                        track.positions.end());
    const float spacing = isk::gltfTrackSpacing(all_frames);
    for (int m = 0; m < kMethodCount; ++m) {
      tracks[m].name = kMethods[m].name;
      tracks[m].offset = {spacing * (m - (kMethodCount - 1) / 2.f), 0, 0};
    }
    const std::string glb =
        (fs::path(out_dir_) / rig_name / "animation.glb").string();
    isk::writeAnimatedGltf(glb, rig.mesh.triangles, tracks,
                           isk::gltfFrameTimes(times));
    std::cerr << prefix << "animation " << glb << " (" << times.size()
              << " frames of " << kMethodCount
              << " methods side by side, morph targets)\n";
  }

  // The pictures, with the implicit pose skinned again for its states.
  const isk::TransformList bent_skinning =
      isk::samples::clipSkinning(rig.skeleton, clip, times[bent.frame]);
  ImplicitPose implicit_pose = skinImplicitPose(
      opencl.get(), rig, fields, implicit_options, bent_skinning);
  const double repeat_difference =
      isk::maxVertexDistance(implicit_pose.positions, bent_positions[2]) /
      diagonal;
  if (!(repeat_difference <= kAgreementTolerance)) {
    std::cerr << prefix << "warning: implicit skinning of frame " << bent.frame
              << " again differs from the frame loop's by "
              << formatNumber("%.2e", repeat_difference)
              << " of the diagonal\n";
  }
  bent_positions[2] = implicit_pose.positions;
  picture_rows_.push_back(
      writeComparePictures(rig_name, rig, bent, times[bent.frame], frame_count,
                           bent_positions, implicit_pose, out_dir_));
  std::cerr << prefix << "pictures "
            << (fs::path(out_dir_) / rig_name / "compare.png").string()
            << ", closeup.png\n";

  if (!job.fields_of.empty()) return;
  if (opencl && !opencl->isReference() && !field_context_) {
    field_context_ = isk::ClContext::create(device_ == "auto" ? "" : device_);
  }
  // The clip's middle frame: the bent pose of the second field picture.
  const double bent_time = times[times.size() / 2];
  field_rows_.push_back(runFields(rig_name, rig, *fields, clip, bent_time,
                                  opencl ? field_context_ : nullptr, out_dir_));
  const FieldRow& field_row = field_rows_.back();
  if (field_row.max_difference &&
      !(*field_row.max_difference <=
        kFieldTolerance[field_row.storage == "image"])) {
    fields_agree_ = false;
  }
}

int Demo::finish() {
  // The composition operators' pictures, as isk-operator-plots draws them.
  const std::string operators_dir = (fs::path(out_dir_) / "operators").string();
  isk::samples::OperatorPlotOptions operator_options;
  operator_options.size = kOperatorPictureSize;
  operator_options.label = "isk-demo: operators";
  const isk::samples::OperatorPlotsReport operator_report =
      isk::samples::writeOperatorPlots(operators_dir, operator_options);
  std::cerr << "isk-demo: " << operator_report.files.size()
            << " operator pictures in " << operators_dir << "\n";
  const std::string table_errors =
      isk::samples::formatTableErrors(operator_report);
  const std::string bend_table = isk::samples::formatBendTable(operator_report);

  std::string frame_note = "Frames per clip (uniformly over the clip): ";
  for (size_t i = 0; i < frame_counts_.size(); ++i) {
    frame_note += (i ? "; " : "") + frame_counts_[i];
  }
  frame_note += frames_ > 0 ? " (--frames " + std::to_string(frames_) + ")."
                            : " (at most " + std::to_string(kDefaultMaxFrames) +
                                  " by default; --frames N to change).";
  std::string skipped;
  for (const std::string& note : notes_) skipped += "\n" + note + ".\n";

  const std::string table = formatTable(rows_);
  const std::string picture_table = formatPictureTable(picture_rows_);
  const std::string field_table = formatFieldTable(field_rows_);
  std::cout << frame_note << "\n\n"
            << table << skipped << "\n"
            << picture_table << "\n"
            << field_table << "\n"
            << table_errors << "\n"
            << bend_table;
  const std::string summary_path = (fs::path(out_dir_) / "summary.md").string();
  isk::writeTextFile(
      summary_path,
      "# isk-demo summary\n\nFrames: " + out_dir_ +
          "/<rig>/<method>/frame_XXXX.obj (the OpenCL frames; the "
          "reference's without an OpenCL device)\n\n" +
          frame_note +
          "\n\nMethods: lbs (linear blend), dqs (dual quaternions), implicit "
          "(Vaillant et al. 2013: DQS, then surface tracking in the rig's "
          "implicit fields with the paper's parameters). Self-intersections: "
          "pairs of non-adjacent triangles that intersect, per frame. "
          "Contact vertices: vertices the tracking stopped at a contact "
          "(median over the frames). ms/frame: skinning + tracking + "
          "normals + read-back, on the device of the row and on the CPU "
          "reference; the last column compares their frames (LBS and DQS "
          "within " +
          formatNumber("%.0e", kAgreementTolerance) + ", implicit within " +
          formatNumber("%.0e", kImplicitAgreementTolerance) +
          " of the diagonal).\n\n" + table + skipped +
          "\n## Pictures\n\nAt each rig's most bent frame (the largest "
          "rotation of a joint relative to its parent bone, from the bind "
          "pose), the three methods side by side, same view and scale, "
          "looking along the joint's bend axis (relative to " +
          out_dir_ +
          "): compare.png (the whole mesh) and closeup.png (around the "
          "joint's fold, seen " +
          formatNumber("%.0f", kCloseUpTiltDegrees) +
          " degrees off the bend axis from inside the fold). Grey: skin; red: "
          "skin seen from inside (pushed through "
          "other skin); green: contact vertices of implicit skinning; dark "
          "lines: silhouettes, folds and creases. Self-intersections and "
          "contact vertices of the pictured frame:\n\n" +
          picture_table +
          "\n## Implicit fields\n\nOne field per bone (HRBF fit, baked "
          "32^3), evaluated at the skinned vertices (DQS) of the bind pose "
          "and of the clip's middle frame on OpenCL and on the CPU "
          "reference. Pictures (relative to " +
          out_dir_ +
          "): the composed field at the bind pose (composed.png) and at the "
          "middle frame (composed_bent.png), inside red, outside blue, the "
          "0.5 iso black, the mesh section green.\n\n" +
          field_table + "\n## Composition operators\n\nPictures in " +
          operators_dir +
          " (see samples/operator-plots/README.md): operator_union.png, "
          "operator_blend.png, operator_bulge.png, each operator's "
          "iso-curves over the (f1, f2) unit square for theta = 0, pi/16, "
          "pi/8, 3pi/16 and pi/4 (left to right). Largest abs(table - "
          "direct) operator value over each panel:\n\n" +
          table_errors +
          "\nbend_<op>_<deg>.png and bend_grid.png (the paper's Figure "
          "5(c)): the arm's composed field around its elbow bent by 0, 45, "
          "90 and 135 degrees with each operator at every joint; areas "
          "within " +
          formatNumber("%.1f", operator_report.measure_radius) +
          " model units of the elbow, compared with the union's:\n\n" +
          bend_table);
  std::cerr << "isk-demo: wrote " << summary_path << "\n";
  int status = 0;
  if (!all_agree_) {
    std::cerr << "isk-demo: OpenCL and the CPU reference differ by more than "
              << kAgreementTolerance << " of the bounding-box diagonal\n";
    status = 1;
  }
  if (!implicit_agree_) {
    std::cerr << "isk-demo: implicit skinning on OpenCL and on the CPU "
                 "reference differ by more than "
              << kImplicitAgreementTolerance
              << " of the bounding-box diagonal\n";
    status = 1;
  }
  if (!fields_agree_) {
    std::cerr << "isk-demo: OpenCL and CPU reference field values differ by "
                 "more than "
              << kFieldTolerance[0] << " (buffer) or " << kFieldTolerance[1]
              << " (image)\n";
    status = 1;
  }
  return status;
}

int run(const std::string& out_dir, int frames, const std::string& device) {
  const auto start = std::chrono::steady_clock::now();
  Demo demo(out_dir, frames, device);
  // The embedded default: the arm and the cylinder with their 90-degree
  // bends, and the cylinder bent to 135 degrees, where its two halves press
  // against each other (the contact case of implicit skinning).
  demo.runRig({"arm", "builtin:arm", 0, ""});
  demo.runRig({"cylinder", "builtin:cylinder", 0, ""});
  demo.runRig({"cylinder-135", "builtin:cylinder", 135, "cylinder"});

  // CesiumMan from the shared data folder, when there.
  const std::string cesium = isk::samples::dataFile("CesiumMan.glb");
  std::error_code ec;
  if (!isk::samples::dataFolderPresent()) {
    demo.skip("CesiumMan",
              "the data folder " + isk::samples::dataFolder() +
                  " does not exist (set ISK_DATA_DIR to the folder holding "
                  "CesiumMan.glb)");
  } else if (!fs::is_regular_file(cesium, ec)) {
    demo.skip("CesiumMan", cesium + " is not in the data folder");
  } else {
    demo.runRig({"CesiumMan", cesium, 0, ""});
  }
  const int status = demo.finish();
  std::cerr << "isk-demo: done in "
            << formatNumber("%.1f",
                            std::chrono::duration<double>(
                                std::chrono::steady_clock::now() - start)
                                .count())
            << " s\n";
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "out";
  int frames = 0;
  std::string device = "auto";
  CLI::App app{
      "Skins the builtin arm and cylinder rigs (and CesiumMan from the data "
      "folder when there) with LBS, DQS and implicit skinning on OpenCL and "
      "on the CPU reference, draws the three methods at each rig's most "
      "bent frame, builds and evaluates the implicit fields; writes frames, "
      "pictures and a summary with the tables."};
  app.add_option("--out", out_dir, "output folder")->capture_default_str();
  app.add_option("--frames", frames,
                 "frames per clip (default: 30 per second of the clip, at "
                 "most 31)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--device", device,
                 "OpenCL device: auto, gpu, cpu or opencl:N")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    return run(out_dir, frames, device);
  } catch (const std::exception& error) {
    std::cerr << "isk-demo: error: " << error.what() << "\n";
  }
  return 1;
}
