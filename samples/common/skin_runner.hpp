// The frame loop shared by isk-skin and the demo: load a rig, pick a clip,
// skin it frame by frame on an OpenCL device or on the CPU reference, time
// the stages, measure quality and write the frames.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "isk/animation.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/cpu_skinning.hpp"
#include "isk/export.hpp"
#include "isk/rig.hpp"
#include "isk/skinning.hpp"
#include "isk/types.hpp"
#include "isk/vertex_normals.hpp"

namespace isk::samples {

// "builtin:NAME" builds a procedural rig, anything else is imported from a
// file. Throws isk::Error.
Rig loadRig(const std::string& input);

// The clip named `spec`, else the clip whose index `spec` spells; an empty
// spec means clip 0. A rig without clips gets a 90-degree bend of every joint
// over 1 s, and `note` says so. Throws isk::Error(kInvalidArgument) listing
// the available clips when `spec` matches none.
AnimationClip selectClip(const Rig& rig, const std::string& spec,
                         std::string* note);

// 30 frames per second of the clip plus the first key, at least 1.
int defaultFrameCount(const AnimationClip& clip);

// `frames` times spread uniformly from the clip's start to its end (the
// start alone for one frame). Throws isk::Error(kInvalidArgument) for < 1.
std::vector<double> frameTimes(const AnimationClip& clip, int frames);

// "frame_0000.obj", "frame_0001.ply", ...
std::string frameFileName(int frame, MeshFormat format);

// Makes `dir` ready for frame files: creates it when missing; when it
// already holds frame files, refuses (isk::Error kIo) unless `overwrite`, in
// which case those old frame files are removed so no stale frame survives.
// Never removes `protected_path` (the input) and refuses a folder where a
// frame file would replace it.
void prepareOutputFolder(const std::string& dir, bool overwrite,
                         const std::string& protected_path);

// Skins one rig on one device: an OpenCL device through isk::ClSkinning, or
// the CPU reference through its twin isk::CpuSkinning.
class FrameSkinner {
 public:
  // `device`: "auto" or "" (default OpenCL device), "reference" (CPU), or an
  // isk::ClContext::create selection such as "opencl:1". Uploads the rig's
  // static data; throws isk::Error.
  FrameSkinner(const Rig& rig, const std::string& device);

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
};

struct RunOptions {
  SkinningMethod method = SkinningMethod::kDualQuaternion;
  std::vector<double> times;  // seconds, one per frame
  std::string out_dir;        // empty: no frame files
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
  std::vector<double> frame_ms;  // skinning + normals + readback, per frame
  TimeSummary frame;
  SkinningStageTimes stage_median;
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
// bind-pose run that measures rest_pose_error (and warms the device up).
RunResult runFrames(const Rig& rig, const AnimationClip& clip,
                    FrameSkinner& skinner, const RunOptions& options);

// Median (mean of the middle two for an even count), nearest-rank p95, min.
TimeSummary summarize(std::vector<double> values);

}  // namespace isk::samples
