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
// Needs no input file. The tables, the frame counts and the pictures' views
// and texts are in samples/common/demo_tables and demo_views.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "data_folder.hpp"
#include "demo_tables.hpp"
#include "demo_views.hpp"
#include "field_pictures.hpp"
#include "isk/cl/field_evaluation.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/export.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/io/rig_params.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/pose.hpp"
#include "isk/tools/mesh_metrics.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "mesh_render.hpp"
#include "operator_plots.hpp"
#include "skin_runner.hpp"

namespace {

namespace fs = std::filesystem;
namespace demo = isk::samples::demo;
using demo::BentFrame;
using demo::FieldRow;
using demo::kMethodCount;
using demo::kMethods;
using demo::MethodSpec;
using demo::PictureRow;
using demo::Row;
using isk::samples::FrameSkinner;
using isk::samples::RunResult;

constexpr double kPi = 3.14159265358979323846;

// Longer side of the field pictures, in pixels.
constexpr int kPictureSize = 512;
// Side of each operator panel and bend picture: smaller than
// isk-operator-plots' default to keep the demo quick.
constexpr int kOperatorPictureSize = 256;
// Side of each (square) panel of compare.png and closeup.png.
constexpr int kPanelSize = 400;

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

// One rig of the demo as the steps of Demo::runRig see it.
struct RigScene {
  std::string name;
  std::string prefix;  // "isk-demo: <rig>: "
  isk::Rig rig;
  double diagonal = 0;
  isk::AnimationClip clip;
  int frame_count = 0;
  std::vector<double> times;
  BentFrame bent;
  std::shared_ptr<const isk::ImplicitFields> fields;
};

// What the frame loops hand the animation and the pictures, per method.
struct MethodFrames {
  // The written frames (OpenCL's when there is a device), played side by
  // side in out/<rig>/animation.glb.
  std::vector<isk::GltfTrack> tracks =
      std::vector<isk::GltfTrack>(kMethodCount);
  isk::Matrix3Xf bent[kMethodCount];  // at the most bent frame
};

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

// The three methods' meshes `positions` in one picture, seen through `view`,
// the implicit panel's vertices in `implicit_colours`.
isk::samples::Image renderPanels(
    const isk::Rig& rig, const isk::Matrix3Xf (&positions)[kMethodCount],
    const isk::samples::RenderView& view,
    const std::vector<isk::samples::Rgb>& implicit_colours,
    const std::vector<std::string>& captions, const std::string& title) {
  std::vector<isk::samples::Image> panels;
  for (int m = 0; m < kMethodCount; ++m) {
    isk::samples::RenderStyle style;
    if (kMethods[m].implicit) style.vertex_colours = &implicit_colours;
    panels.push_back(isk::samples::renderMesh(
        positions[m], rig.mesh.triangles, view, kPanelSize, kPanelSize, style));
  }
  return isk::samples::sideBySide(panels, captions, title);
}

// Draws the three methods' meshes at the most bent frame side by side, same
// view and scale (demo::comparisonViews), the implicit panel's contact
// vertices tinted. Writes out_dir/<rig>/compare.png (the whole meshes) and
// closeup.png (around the joint's fold, turned towards its inside) and
// returns the table row.
PictureRow writeComparePictures(const RigScene& scene,
                                const isk::Matrix3Xf (&positions)[kMethodCount],
                                const ImplicitPose& implicit_pose,
                                const std::string& out_dir) {
  const isk::Rig& rig = scene.rig;
  const BentFrame& bent = scene.bent;
  PictureRow row = demo::describePictures(
      scene.name, rig, bent, scene.times[bent.frame], positions,
      implicit_pose.states, implicit_pose.vertex_groups);
  const std::vector<isk::samples::Rgb> colours =
      demo::contactColours(rig.mesh.vertexCount(), implicit_pose.states);
  const demo::ComparisonViews views =
      demo::comparisonViews(rig, bent, positions);
  const std::vector<std::string> captions = demo::methodCaptions(row);
  const std::string title = demo::pictureTitle(row, bent, scene.frame_count);
  const std::string legend =
      "\ngreen: contact vertices, red: skin seen from inside (pushed through "
      "skin)";

  const fs::path rig_dir = fs::path(out_dir) / scene.name;
  fs::create_directories(rig_dir);
  const struct {
    const char* file;
    const isk::samples::RenderView& view;
    std::string suffix;
  } pictures[] = {
      {"compare.png", views.whole,
       bent.joint >= 0 ? "\nseen along the bend axis" : ""},
      {"closeup.png", views.close, ", close-up\n" + views.close_legend}};
  for (const auto& picture : pictures) {
    isk::samples::writePng(
        (rig_dir / picture.file).string(),
        renderPanels(rig, positions, picture.view, colours, captions,
                     title + picture.suffix + legend));
    row.pictures.push_back((fs::path(scene.name) / picture.file).string());
  }
  return row;
}

// A pose of the field pictures: its skinning and the mesh posed by it.
struct FieldPose {
  const char* picture;
  const isk::TransformList& skinning;
  const isk::Matrix3Xf& positions;
};

// The largest |OpenCL - reference| composed field value at `pose`'s mesh.
double fieldDifference(const isk::ImplicitFields& fields,
                       isk::ClFieldEvaluation& evaluation,
                       const FieldPose& pose) {
  const isk::Matrix4Xf reference = isk::evaluateComposedField(
      fields.grids, pose.skinning, pose.positions, &fields.composition);
  isk::Matrix4Xf opencl;
  evaluation.evaluate(pose.skinning, pose.positions, opencl);
  return (opencl.col(0) - reference.col(0)).cwiseAbs().maxCoeff();
}

// Describes the `fields` built for the scene's rig (fit+bake times measured
// by the build), compares OpenCL (when `context` is set) with the reference
// at the skinned vertices of the bind pose and of the clip at `bent_time`,
// and draws both poses under out_dir/<rig>/fields/.
FieldRow runFields(const RigScene& scene, double bent_time,
                   const std::shared_ptr<isk::ClContext>& context,
                   const std::string& out_dir) {
  const isk::Rig& rig = scene.rig;
  const isk::ImplicitFields& fields = *scene.fields;
  FieldRow row = demo::describeFields(scene.name, fields);

  // Bind pose: the rest mesh; bent: the clip's middle frame, skinned with
  // DQS like the pictures of isk-field-slices.
  const isk::TransformList bind = isk::bindPoseSkinning(rig.skeleton);
  const isk::TransformList bent =
      isk::samples::clipSkinning(rig.skeleton, scene.clip, bent_time);
  const isk::Matrix3Xf bent_positions = isk::samples::dqsPositions(rig, bent);
  const FieldPose poses[] = {{"composed.png", bind, rig.mesh.positions},
                             {"composed_bent.png", bent, bent_positions}};

  std::unique_ptr<isk::ClFieldEvaluation> evaluation;
  if (context && row.fields > 0) {
    evaluation = std::make_unique<isk::ClFieldEvaluation>(
        context, fields.grids, rig.skeleton.jointCount(),
        isk::FieldStorage::kAuto, &fields.composition);
    row.storage = isk::fieldStorageName(evaluation->storage());
    row.max_difference = 0.0;
  }
  const fs::path fields_dir = fs::path(out_dir) / scene.name / "fields";
  fs::create_directories(fields_dir);
  for (const FieldPose& pose : poses) {
    if (evaluation) {
      row.max_difference = std::max<double>(
          *row.max_difference, fieldDifference(fields, *evaluation, pose));
    }
    if (row.fields > 0) {
      isk::samples::writeComposedPicture((fields_dir / pose.picture).string(),
                                         rig, fields, pose.skinning,
                                         pose.positions, kPictureSize);
      row.pictures.push_back(
          (fs::path(scene.name) / "fields" / pose.picture).string());
    }
  }
  std::cerr << scene.prefix << row.fields << " fields, pictures in "
            << fields_dir.string() << "\n";
  return row;
}

// The rig of `job`, its warnings said.
isk::Rig loadJobRig(const RigJob& job, const std::string& prefix) {
  isk::Rig rig =
      isk::samples::loadRig(job.source, isk::samples::guardedImportOptions());
  for (const std::string& warning : rig.warnings) {
    std::cerr << prefix << "warning: " << warning << "\n";
  }
  return rig;
}

// The rig's first clip (a procedural bend without one), or the job's bend.
isk::AnimationClip jobClip(const isk::Rig& rig, const RigJob& job,
                           const std::string& prefix) {
  std::string clip_note;
  isk::AnimationClip clip = isk::samples::selectClip(rig, "", &clip_note);
  if (!clip_note.empty()) std::cerr << prefix << clip_note << "\n";
  if (job.bend_degrees > 0) {
    clip = isk::makeBendClip(
        rig.skeleton, static_cast<float>(job.bend_degrees * kPi / 180), 1.0);
    clip.name = "bend-" + demo::formatNumber("%.0f", job.bend_degrees);
  }
  return clip;
}

// Builds the rig's fields, cached on disk (ISK_CACHE_DIR; "off" disables
// it), with an asset's <asset>.isk.json parameters when present.
std::shared_ptr<const isk::ImplicitFields> buildJobFields(
    const RigJob& job, const isk::Rig& rig, const std::string& prefix) {
  isk::ImplicitFieldsOptions field_options;
  field_options.cache = true;
  const std::string params_path = isk::samples::paramsFileBeside(job.source);
  if (!params_path.empty()) {
    isk::applyRigParams(isk::loadRigParams(params_path, &rig.skeleton),
                        &field_options);
    std::cerr << prefix << "parameters from " << params_path << "\n";
  }
  auto fields = std::make_shared<const isk::ImplicitFields>(
      isk::samples::buildFieldsWithProgress(rig, field_options,
                                            prefix + "building fields",
                                            prefix + "warning: "));
  if (fields->cache_origin == isk::FieldCacheOrigin::kLoaded)
    std::cerr << prefix << "fields loaded from the cache " << fields->cache_file
              << "\n";
  else if (fields->cache_origin == isk::FieldCacheOrigin::kRebuilt)
    std::cerr << prefix << "fields rebuilt (" << fields->cache_note << ")\n";
  return fields;
}

// What runs on the rig, and the frame of its pictures.
void sayWhatRuns(const RigScene& scene) {
  std::cerr << scene.prefix << scene.rig.mesh.vertexCount() << " vertices, "
            << scene.times.size() << " frames of clip '" << scene.clip.name
            << "'; pictures at frame " << scene.bent.frame;
  if (scene.bent.joint >= 0) {
    std::cerr << " (" << scene.rig.skeleton.joints[scene.bent.joint].name
              << " bent " << demo::formatNumber("%.1f", scene.bent.degrees)
              << " deg)";
  }
  std::cerr << "\n";
}

// Writes out/<rig>/animation.glb: LBS, DQS and implicit side by side, 1.2
// bounding-box widths apart.
void writeAnimation(const RigScene& scene, const std::string& out_dir,
                    std::vector<isk::GltfTrack>& tracks) {
  for (int m = 0; m < kMethodCount; ++m) tracks[m].name = kMethods[m].name;
  isk::samples::placeSideBySide(tracks);
  const std::string glb =
      (fs::path(out_dir) / scene.name / "animation.glb").string();
  isk::writeAnimatedGltf(glb, scene.rig.mesh.triangles, tracks,
                         isk::gltfFrameTimes(scene.times));
  std::cerr << scene.prefix << "animation " << glb << " (" << scene.times.size()
            << " frames of " << kMethodCount
            << " methods side by side, morph targets)\n";
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
  // The steps of runRig.
  RigScene prepareScene(const RigJob& job);
  std::shared_ptr<const isk::ImplicitFields> fieldsFor(
      const RigJob& job, const isk::Rig& rig, const std::string& prefix);
  std::unique_ptr<FrameSkinner> openClSkinner(const isk::Rig& rig);
  void runMethod(const RigScene& scene, int m, FrameSkinner& reference,
                 FrameSkinner* opencl, MethodFrames& frames);
  void compareDevices(const RigScene& scene, const MethodSpec& method,
                      double max_difference, const RunResult& opencl_result,
                      const RunResult& reference_result);
  void writePictures(const RigScene& scene, FrameSkinner* opencl,
                     const isk::ImplicitSkinnerOptions& implicit_options,
                     MethodFrames& frames);
  void addFieldRow(const RigScene& scene, bool with_opencl);

  // The steps of finish.
  isk::samples::OperatorPlotsReport writeOperatorPictures(
      const std::string& operators_dir);
  demo::Summary makeSummary(
      const std::string& operators_dir,
      const isk::samples::OperatorPlotsReport& operators) const;

  std::string out_dir_;
  int frames_;
  std::string device_;
  std::vector<Row> rows_;
  std::vector<FieldRow> field_rows_;
  std::vector<PictureRow> picture_rows_;
  std::vector<std::string> notes_;
  std::vector<std::string> frame_counts_;  // "rig: N of M"
  demo::Agreement agreement_;
  // One OpenCL context for the field evaluations, made with the first rig
  // that has an OpenCL device.
  std::shared_ptr<isk::ClContext> field_context_;
  std::map<std::string, std::shared_ptr<const isk::ImplicitFields>> fields_;
};

void Demo::runRig(const RigJob& job) {
  const RigScene scene = prepareScene(job);
  // The paper's tracking, started from DQS, on the fields just built (with
  // the default options, which ImplicitSkinnerOptions::fields holds too).
  const isk::ImplicitSkinnerOptions implicit_options;

  FrameSkinner reference(scene.rig, "reference");
  reference.enableImplicit(scene.rig, scene.fields, implicit_options);
  std::unique_ptr<FrameSkinner> opencl = openClSkinner(scene.rig);
  if (opencl) opencl->enableImplicit(scene.rig, scene.fields, implicit_options);
  sayWhatRuns(scene);

  MethodFrames frames;
  for (int m = 0; m < kMethodCount; ++m) {
    runMethod(scene, m, reference, opencl.get(), frames);
  }
  writeAnimation(scene, out_dir_, frames.tracks);
  writePictures(scene, opencl.get(), implicit_options, frames);
  if (job.fields_of.empty()) {
    addFieldRow(scene, opencl && !opencl->isReference());
  }
}

// The rig, its clip and frames, the pose of its pictures and its fields.
RigScene Demo::prepareScene(const RigJob& job) {
  RigScene scene;
  scene.name = job.name;
  scene.prefix = "isk-demo: " + job.name + ": ";
  scene.rig = loadJobRig(job, scene.prefix);
  scene.clip = jobClip(scene.rig, job, scene.prefix);
  const demo::FramePlan plan = demo::planFrames(frames_, scene.clip);
  scene.frame_count = plan.count;
  frame_counts_.push_back(demo::describeFramePlan(job.name, plan));
  scene.times = isk::samples::frameTimes(scene.clip, scene.frame_count);
  scene.diagonal = scene.rig.boundingBoxDiagonal();
  scene.bent = demo::mostBentFrame(scene.rig.skeleton, scene.clip, scene.times);
  scene.fields = fieldsFor(job, scene.rig, scene.prefix);
  return scene;
}

// The fields of the rig `job.fields_of` when built already, else built.
std::shared_ptr<const isk::ImplicitFields> Demo::fieldsFor(
    const RigJob& job, const isk::Rig& rig, const std::string& prefix) {
  if (const auto it = fields_.find(job.fields_of); it != fields_.end()) {
    return it->second;
  }
  auto fields = buildJobFields(job, rig, prefix);
  fields_[job.name] = fields;
  return fields;
}

// The skinner of the OpenCL device; null, said on stderr, without one.
std::unique_ptr<FrameSkinner> Demo::openClSkinner(const isk::Rig& rig) {
  try {
    return std::make_unique<FrameSkinner>(rig, device_);
  } catch (const isk::Error& error) {
    if (error.code() != isk::ErrorCode::kNoDevice) throw;
    std::cerr << "isk-demo: no OpenCL device (" << error.what()
              << "); writing the CPU reference frames only\n";
  }
  return nullptr;
}

// The frame loop's options for kMethods[m] over the scene's frames.
isk::samples::RunOptions methodRunOptions(const RigScene& scene, int m) {
  isk::samples::RunOptions options;
  options.method = kMethods[m].method;
  options.implicit = kMethods[m].implicit;
  options.times = scene.times;
  return options;
}

// Method m on the CPU reference, its frames kept in `reference_frames` so
// that the OpenCL run can be compared with them frame by frame. Without
// OpenCL (`frames_dir` set), its frames are the ones written, pictured and
// animated, and its self-intersections are counted.
RunResult runOnReference(const RigScene& scene, int m, FrameSkinner& reference,
                         const std::string& frames_dir, MethodFrames& frames,
                         std::vector<isk::Matrix3Xf>& reference_frames) {
  const bool written = !frames_dir.empty();
  isk::samples::RunOptions options = methodRunOptions(scene, m);
  options.quality = written;
  options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                         const isk::Matrix3Xf& normals) {
    reference_frames.push_back(positions);
    if (frame == scene.bent.frame) frames.bent[m] = positions;
    if (written) {
      frames.tracks[m].positions.push_back(positions);
      frames.tracks[m].normals.push_back(normals);
    }
  };
  options.out_dir = frames_dir;
  return isk::samples::runFrames(scene.rig, scene.clip, reference, options);
}

// Method m on OpenCL, its frames written to `frames_dir`, pictured and
// animated; `max_difference` is the largest distance from the reference's
// `reference_frames` over the bounding-box diagonal.
RunResult runOnOpenCl(const RigScene& scene, int m, FrameSkinner& opencl,
                      const std::string& frames_dir,
                      const std::vector<isk::Matrix3Xf>& reference_frames,
                      MethodFrames& frames, double& max_difference) {
  isk::samples::RunOptions options = methodRunOptions(scene, m);
  options.out_dir = frames_dir;
  options.quality = true;
  options.on_frame = [&](int frame, const isk::Matrix3Xf& positions,
                         const isk::Matrix3Xf& normals) {
    const double distance =
        isk::maxVertexDistance(positions, reference_frames[frame]);
    max_difference = std::max(max_difference, distance / scene.diagonal);
    if (frame == scene.bent.frame) frames.bent[m] = positions;
    frames.tracks[m].positions.push_back(positions);
    frames.tracks[m].normals.push_back(normals);
  };
  return isk::samples::runFrames(scene.rig, scene.clip, opencl, options);
}

// Skins the scene with method m on the reference, then on OpenCL (when
// there is a device), comparing the two frame by frame; writes the frames
// (OpenCL's when there is a device) and adds the table row.
void Demo::runMethod(const RigScene& scene, int m, FrameSkinner& reference,
                     FrameSkinner* opencl, MethodFrames& frames) {
  const MethodSpec& method = kMethods[m];
  const std::string frames_dir =
      (fs::path(out_dir_) / scene.name / method.name).string();
  isk::samples::prepareOutputFolder(frames_dir, /*overwrite=*/true, "");

  std::vector<isk::Matrix3Xf> reference_frames;
  const RunResult reference_result = runOnReference(
      scene, m, reference, opencl ? "" : frames_dir, frames, reference_frames);
  if (!opencl) {
    rows_.push_back(demo::makeRow(scene.name, scene.clip, method,
                                  "reference (CPU)", reference_result));
    return;
  }
  double max_difference = 0;
  const RunResult opencl_result = runOnOpenCl(
      scene, m, *opencl, frames_dir, reference_frames, frames, max_difference);
  Row row = demo::makeRow(scene.name, scene.clip, method, opencl->describe(),
                          opencl_result);
  row.reference_ms = reference_result.frame.median;
  row.max_difference = max_difference;
  rows_.push_back(row);
  compareDevices(scene, method, max_difference, opencl_result,
                 reference_result);
}

// Says how OpenCL compared with the reference (and records a
// disagreement, which fails the demo).
void Demo::compareDevices(const RigScene& scene, const MethodSpec& method,
                          double max_difference, const RunResult& opencl_result,
                          const RunResult& reference_result) {
  const double tolerance = method.implicit ? demo::kImplicitAgreementTolerance
                                           : demo::kAgreementTolerance;
  if (!(max_difference <= tolerance)) {
    (method.implicit ? agreement_.implicit : agreement_.skinning) = false;
    std::cerr << scene.prefix << method.name
              << ": OpenCL and the CPU reference differ by "
              << demo::formatNumber("%.2e", max_difference)
              << " of the bounding-box diagonal (tolerance "
              << demo::formatNumber("%.0e", tolerance) << ")\n";
  }
  std::cerr << scene.prefix << method.name << ": "
            << demo::formatNumber("%.3f", opencl_result.frame.median)
            << " ms/frame on OpenCL, "
            << demo::formatNumber("%.3f", reference_result.frame.median)
            << " on the reference\n";
}

// The comparison pictures, with the implicit pose skinned again for its
// states.
void Demo::writePictures(const RigScene& scene, FrameSkinner* opencl,
                         const isk::ImplicitSkinnerOptions& implicit_options,
                         MethodFrames& frames) {
  const int bent_frame = scene.bent.frame;
  const isk::TransformList bent_skinning = isk::samples::clipSkinning(
      scene.rig.skeleton, scene.clip, scene.times[bent_frame]);
  const ImplicitPose implicit_pose = skinImplicitPose(
      opencl, scene.rig, scene.fields, implicit_options, bent_skinning);
  const double repeat_difference =
      isk::maxVertexDistance(implicit_pose.positions, frames.bent[2]) /
      scene.diagonal;
  if (!(repeat_difference <= demo::kAgreementTolerance)) {
    std::cerr << scene.prefix << "warning: implicit skinning of frame "
              << bent_frame << " again differs from the frame loop's by "
              << demo::formatNumber("%.2e", repeat_difference)
              << " of the diagonal\n";
  }
  frames.bent[2] = implicit_pose.positions;
  picture_rows_.push_back(
      writeComparePictures(scene, frames.bent, implicit_pose, out_dir_));
  std::cerr << scene.prefix << "pictures "
            << (fs::path(out_dir_) / scene.name / "compare.png").string()
            << ", closeup.png\n";
}

// The fields' row: evaluated on OpenCL (`with_opencl`: an OpenCL device) and
// on the reference, drawn at the bind pose and at the clip's middle frame.
void Demo::addFieldRow(const RigScene& scene, bool with_opencl) {
  if (with_opencl && !field_context_) {
    field_context_ = isk::ClContext::create(device_ == "auto" ? "" : device_);
  }
  const double bent_time = scene.times[scene.times.size() / 2];
  field_rows_.push_back(runFields(
      scene, bent_time, with_opencl ? field_context_ : nullptr, out_dir_));
  const FieldRow& field_row = field_rows_.back();
  if (field_row.max_difference &&
      !(*field_row.max_difference <=
        demo::kFieldTolerance[field_row.storage == "image"])) {
    agreement_.fields = false;
  }
}

// The composition operators' pictures, as isk-operator-plots draws them.
isk::samples::OperatorPlotsReport Demo::writeOperatorPictures(
    const std::string& operators_dir) {
  isk::samples::OperatorPlotOptions operator_options;
  operator_options.size = kOperatorPictureSize;
  operator_options.label = "isk-demo: operators";
  isk::samples::OperatorPlotsReport report =
      isk::samples::writeOperatorPlots(operators_dir, operator_options);
  std::cerr << "isk-demo: " << report.files.size() << " operator pictures in "
            << operators_dir << "\n";
  return report;
}

// Everything the tables show, with the operators' tables of `operators`.
demo::Summary Demo::makeSummary(
    const std::string& operators_dir,
    const isk::samples::OperatorPlotsReport& operators) const {
  demo::Summary summary;
  summary.out_dir = out_dir_;
  summary.operators_dir = operators_dir;
  summary.frame_note = demo::formatFrameNote(frame_counts_, frames_);
  summary.rows = rows_;
  summary.notes = notes_;
  summary.picture_rows = picture_rows_;
  summary.field_rows = field_rows_;
  summary.table_errors = isk::samples::formatTableErrors(operators);
  summary.bend_table = isk::samples::formatBendTable(operators);
  summary.measure_radius = operators.measure_radius;
  return summary;
}

int Demo::finish() {
  const std::string operators_dir = (fs::path(out_dir_) / "operators").string();
  const demo::Summary tables =
      makeSummary(operators_dir, writeOperatorPictures(operators_dir));
  std::cout << demo::formatStdoutSummary(tables);
  const std::string summary_path = (fs::path(out_dir_) / "summary.md").string();
  isk::writeTextFile(summary_path, demo::formatSummaryMarkdown(tables));
  std::cerr << "isk-demo: wrote " << summary_path << "\n";
  const std::vector<std::string> failures = demo::agreementFailures(agreement_);
  for (const std::string& failure : failures) std::cerr << failure << "\n";
  return failures.empty() ? 0 : 1;
}

// CesiumMan from the shared data folder when it is there; else says why not.
void runCesiumMan(Demo& demo_run) {
  const std::string cesium = isk::samples::dataFile("CesiumMan.glb");
  std::error_code ec;
  if (!isk::samples::dataFolderPresent()) {
    demo_run.skip("CesiumMan",
                  "the data folder " + isk::samples::dataFolder() +
                      " does not exist (set ISK_DATA_DIR to the folder "
                      "holding CesiumMan.glb)");
  } else if (!fs::is_regular_file(cesium, ec)) {
    demo_run.skip("CesiumMan", cesium + " is not in the data folder");
  } else {
    demo_run.runRig({"CesiumMan", cesium, 0, ""});
  }
}

int run(const std::string& out_dir, int frames, const std::string& device) {
  const auto start = std::chrono::steady_clock::now();
  Demo demo_run(out_dir, frames, device);
  // The embedded default: the arm and the cylinder with their 90-degree
  // bends, and the cylinder bent to 135 degrees, where its two halves press
  // against each other (the contact case of implicit skinning).
  demo_run.runRig({"arm", "builtin:arm", 0, ""});
  demo_run.runRig({"cylinder", "builtin:cylinder", 0, ""});
  demo_run.runRig({"cylinder-135", "builtin:cylinder", 135, "cylinder"});
  runCesiumMan(demo_run);
  const int status = demo_run.finish();
  std::cerr << "isk-demo: done in "
            << demo::formatNumber("%.1f", isk::millisecondsSince(start) / 1000)
            << " s\n";
  return status;
}

// The demo's command line.
struct Options {
  std::string out_dir = "out";
  int frames = 0;
  std::string device = "auto";
};

void addOptions(CLI::App& app, Options& options) {
  app.add_option("--out", options.out_dir, "output folder")
      ->capture_default_str();
  app.add_option("--frames", options.frames,
                 "frames per clip (default: 30 per second of the clip, at "
                 "most 31)")
      ->check(CLI::Range(1, 100000));
  app.add_option("--device", options.device,
                 "OpenCL device: auto, gpu, cpu or opencl:N")
      ->capture_default_str();
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  CLI::App app{
      "Skins the builtin arm and cylinder rigs (and CesiumMan from the data "
      "folder when there) with LBS, DQS and implicit skinning on OpenCL and "
      "on the CPU reference, draws the three methods at each rig's most "
      "bent frame, builds and evaluates the implicit fields; writes frames, "
      "pictures and a summary with the tables."};
  addOptions(app, options);
  CLI11_PARSE(app, argc, argv);

  try {
    return run(options.out_dir, options.frames, options.device);
  } catch (const std::exception& error) {
    std::cerr << "isk-demo: error: " << error.what() << "\n";
  }
  return 1;
}
