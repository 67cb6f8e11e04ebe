// The frame loop shared by isk-skin and the demo: load a rig, pick a clip,
// skin it frame by frame on an OpenCL device or on the CPU reference, time
// the stages, measure quality and write the frames; and what else both
// need: builtin inputs and parameter files, counts per frame summed up, the
// animated glTF's layout.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/core/types.hpp"
#include "isk/core/vertex_normals.hpp"
#include "isk/implicit_skinner.hpp"
#include "isk/io/export.hpp"
#include "isk/io/gltf_export.hpp"
#include "isk/io/import.hpp"
#include "isk/rig/animation.hpp"
#include "isk/rig/rig.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/skinning/skinning.hpp"
#include "isk/tools/skin_quality.hpp"

namespace isk::samples {

// "builtin:NAME" builds a procedural rig, anything else is imported from a
// file with `options` (their progress is replaced by a progress line on
// stderr). Throws isk::Error.
Rig loadRig(const std::string& input, ImportOptions options = {});

// True for "builtin:NAME" (a procedural rig), false for a file.
bool isBuiltinInput(const std::string& input);

// True when `a` and `b` name one existing file (or folder).
bool samePath(const std::string& a, const std::string& b);

// The per-joint parameter file beside a file input (<input>.isk.json,
// isk::rigParamsPathFor) when it exists; empty for a builtin input and when
// there is none.
std::string paramsFileBeside(const std::string& input);

// How the samples import files by default: in a child process stopped after
// two minutes, since some corrupt files make Assimp hang (isk/io/import.hpp).
constexpr double kImportTimeLimitSeconds = 120;
inline ImportOptions guardedImportOptions() {
  ImportOptions options;
  options.time_limit_seconds = kImportTimeLimitSeconds;
  return options;
}

// The clips every rig has besides its own: "rest" (the bind pose, no
// channel) and "bend[:DEGREES]" (every joint bent from 0 to DEGREES, default
// 90, over 1 s: isk::makeBendClip). Unset for any other spec; throws
// isk::Error(kInvalidArgument) for an angle that is not 0 to 180.
std::optional<AnimationClip> proceduralClip(const Skeleton& skeleton,
                                            const std::string& spec);

// The clip named `spec`, else a procedural clip (proceduralClip), else the
// clip whose index `spec` spells; an empty spec means clip 0. A rig without
// clips gets a 90-degree bend of every joint over 1 s, and `note` says so.
// Throws isk::Error(kInvalidArgument) listing the available clips when
// `spec` matches none.
AnimationClip selectClip(const Rig& rig, const std::string& spec,
                         std::string* note);

// 30 frames per second of the clip plus the first key, at least 1 and at
// most INT_MAX (a corrupt key time can make a clip last for ages).
int defaultFrameCount(const AnimationClip& clip);

// `frames` times spread uniformly from the clip's start to its end (the
// start alone for one frame). Throws isk::Error(kInvalidArgument) for < 1.
std::vector<double> frameTimes(const AnimationClip& clip, int frames);

// "frame_0000.obj", "frame_0001.ply", ...
std::string frameFileName(int frame, MeshFormat format);

// Makes `dir` ready for frame files: creates it when missing; when it
// exists and holds anything, refuses (isk::Error kIo, listing a few entries)
// unless `overwrite`, in which case the old frame files
// (frame_NNNN.obj|ply) are removed so no stale frame survives, and every
// other file stays. Never removes `protected_path` (the input) and refuses a
// folder where it has a frame file's name.
void prepareOutputFolder(const std::string& dir, bool overwrite,
                         const std::string& protected_path);

// Named stage times of one frame, in pipeline order.
using StageTimes = std::vector<std::pair<std::string, double>>;

// Skins one rig on one device: an OpenCL device through isk::ClSkinning (and
// isk::ImplicitSkinner), or the CPU reference through their twins
// isk::CpuSkinning (and isk::CpuImplicitSkinner).
class FrameSkinner {
 public:
  // `device`: "auto" or "" (default OpenCL device), "reference" (CPU), or an
  // isk::ClContext::create selection such as "opencl:1". Uploads the rig's
  // static data; throws isk::Error.
  FrameSkinner(const Rig& rig, const std::string& device);

  // Adds implicit skinning with `fields` built for this rig (shared, not
  // copied) on the same device; skinImplicit() needs it.
  void enableImplicit(const Rig& rig,
                      std::shared_ptr<const ImplicitFields> fields,
                      const ImplicitSkinnerOptions& options);
  bool hasImplicit() const { return implicit_device_ || implicit_reference_; }
  // Implicit skinning of one frame (base skinning, tracking, normals); fills
  // lastStages().
  void skinImplicit(const TransformList& skinning, Matrix3Xf& positions,
                    Matrix3Xf& normals);
  // Vertices stopped at a contact by the last skinImplicit().
  int lastContactCount();
  // The tracking states of the last skinImplicit(), #V (a blocking read on
  // the device); empty without implicit skinning.
  void lastTrackStates(std::vector<TrackState>& out);
  // The tracking mesh of the implicit skinner (its welded vertex groups).
  const TrackingMesh* trackingMesh() const;

  bool isReference() const { return !device_; }
  // Null for the reference.
  const ClDeviceInfo* deviceInfo() const;
  // "reference (CPU)" or "platform / device".
  std::string describe() const;

  // Skins the rest mesh with `skinning` transforms and recomputes normals
  // from the result; fills lastTimes().
  void skin(SkinningMethod method, const TransformList& skinning,
            Matrix3Xf& positions, Matrix3Xf& normals);
  const SkinningStageTimes& lastTimes() const {
    return device_ ? device_->lastTimes() : reference_->lastTimes();
  }
  // The last skin()'s or skinImplicit()'s stage times: upload, skinning,
  // normals, readback; or upload, skinning, projection, relaxation,
  // smoothing, normals, readback.
  const StageTimes& lastStages() const { return stages_; }

  // The OpenCL context (null for the reference), so that other device work
  // such as isk::ClFieldEvaluation shares its queue and buffers.
  std::shared_ptr<ClContext> sharedContext() const { return context_; }
  // The last skin()'s positions on the device, #V * 3 packed floats (null
  // for the reference).
  const cl::Buffer* devicePositions() const {
    return device_ ? &device_->positionsBuffer() : nullptr;
  }

 private:
  std::shared_ptr<ClContext> context_;      // set for OpenCL
  std::unique_ptr<ClSkinning> device_;      // set for OpenCL
  std::unique_ptr<CpuSkinning> reference_;  // set for the reference
  std::unique_ptr<ImplicitSkinner> implicit_device_;
  std::unique_ptr<CpuImplicitSkinner> implicit_reference_;
  StageTimes stages_;
};

struct RunOptions {
  SkinningMethod method = SkinningMethod::kDualQuaternion;
  // Implicit skinning (the skinner's enableImplicit) instead of `method`.
  bool implicit = false;
  // Measure every frame's quality (isk/tools/skin_quality.hpp, outside the
  // frame timings): self-intersecting pairs, volume, edge strain, distance
  // from DQS (skinned again on the CPU reference), jitter, lost vertices.
  bool quality = false;
  std::vector<double> times;  // seconds, one per frame
  // A frame range's warm-up: times skinned after the bind pose and before
  // `times`, neither measured nor written (history-dependent tracking starts
  // each frame from the one before).
  std::vector<double> warm_up_times;
  // The number of times[0] in the whole clip's frames: frame files are
  // numbered from it, so that ranges run apart make one sequence.
  int first_frame = 0;
  std::string out_dir;  // empty: no frame files
  MeshFormat format = MeshFormat::kObj;
  bool progress = false;  // "\r[frame i/N]" on stderr
  // Called with each frame's output, e.g. to compare two devices.
  std::function<void(int frame, const Matrix3Xf& positions,
                     const Matrix3Xf& normals)>
      on_frame;
};

struct TimeSummary {
  double median = 0;
  double p95 = 0;
  double min = 0;
};

struct RunResult {
  int frames = 0;
  int first_frame = 0;           // RunOptions::first_frame
  int warm_up_frames = 0;        // RunOptions::warm_up_times' count
  std::vector<double> frame_ms;  // skinning + normals + readback, per frame
  TimeSummary frame;
  StageTimes stage_median;  // per stage, median over the frames
  // Per frame, when asked: the quality measures, and the frame's
  // self-intersecting pairs new against the rest pose (fold-overs of
  // adjacent triangles included); vertices stopped at a contact (implicit).
  std::vector<FrameQuality> quality;
  std::vector<int> self_intersections;
  std::vector<int> contact_vertices;
  // Per frame, implicit with the quality measured: the vertices whose
  // tracking state (converged, contact, crease, lost, ...) differs from the
  // frame before's; unset on the first frame, which has none before it.
  // Contacts and creases that come and go switch the smoothing around them
  // on and off: where the frames pop.
  std::vector<std::optional<int>> state_changes;
  // Intersecting pairs of the rest pose (when quality was measured).
  int rest_self_intersections = 0;
  double rest_volume = 0;
  // Unset when the rest volume is about 0 (an open or flat mesh), where
  // a ratio means nothing.
  std::optional<double> volume_ratio_min, volume_ratio_max;
  // Largest distance between the bind-pose output and the input positions
  // over the bounding-box diagonal.
  double rest_pose_error = 0;
  std::vector<std::string> files;  // written frame files
};

// Skins `rig` at every time of `options.times` with `clip`, after one
// bind-pose run that measures rest_pose_error (and warms the device up) and
// the warm-up frames (options.warm_up_times).
// A frame whose output holds a non-finite position or normal is an error
// (isk::Error kInternal naming the vertex), never written. When a frame
// fails, the isk::Error thrown keeps the failure's code and says which
// frame failed and which frame files were written before it (each is
// complete: written to a temporary name, then renamed).
RunResult runFrames(const Rig& rig, const AnimationClip& clip,
                    FrameSkinner& skinner, const RunOptions& options);

// Median (mean of the middle two for an even count), nearest-rank p95, min.
TimeSummary summarize(std::vector<double> values);

// Median of per-frame counts (0 for none), as summarize() takes it.
double medianCount(const std::vector<int>& counts);

// The largest of per-frame counts and their sum (both 0 for none).
struct CountTotals {
  int max = 0;
  long long total = 0;
};
CountTotals countTotals(const std::vector<int>& counts);

// How many vertices' tracking states differ between two frames' (both of
// the mesh's vertex count).
int changedStates(const std::vector<TrackState>& before,
                  const std::vector<TrackState>& after);

// Mean and largest of the per-frame state changes that are set; unset
// when none is.
struct StateChangeSummary {
  double mean = 0;
  int max = 0;
};
std::optional<StateChangeSummary> summarizeStateChanges(
    const std::vector<std::optional<int>>& changes);

// Places `tracks` side by side along x in their order, centred on the
// middle one, isk::gltfTrackSpacing (over every frame of every track)
// apart: the layout of isk-skin's --gltf and the demo's animation.glb.
void placeSideBySide(std::vector<GltfTrack>& tracks);

}  // namespace isk::samples
