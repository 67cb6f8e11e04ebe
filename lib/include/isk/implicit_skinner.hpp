// Implicit skinning end to end (Vaillant et al. 2013): build once from a rig,
// then per frame joint transforms in, positions and normals out.
//
//   isk::ImplicitSkinner skinner(isk::ClContext::create(), rig);
//   skinner.run(isk::skinningTransforms(rig.skeleton, pose));
//   skinner.readPositions(positions);  // or positionsBuffer() for interop
//
// Building (offline, on the CPU): the rig's implicit fields
// (isk/fields/implicit_fields.hpp: partition, HRBF fits, 32^3 grids, operators
// per joint, iso values), the one-rings and mean value weights of tracking
// (isk/tracking/surface_tracking.hpp), then one upload. A frame on the device:
// geometric skinning (dual quaternions by default, LBS as an option) ->
// rounds of (projection steps with the 55 degree contact stop, tangential
// relaxation) -> beta diffusion and localized Laplacian smoothing ->
// normals; everything stays on the device, nothing is read back inside the
// frame. A vertex stopped (converged, at a contact, or out of every field)
// does no more work; a vertex carried rigidly by one bone, far from the
// others' supports, converges at its first step.
//
// Several skinners may share one ClContext (its program cache included).
// CpuImplicitSkinner is the single-thread CPU reference with the same calls.
#pragma once

#include <memory>

#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/cl/skinning.hpp"
#include "isk/cl/surface_tracking.hpp"
#include "isk/fields/implicit_fields.hpp"
#include "isk/rig/rig.hpp"
#include "isk/skinning/cpu_skinning.hpp"
#include "isk/tracking/surface_tracking.hpp"
#include "isk/tracking/tracking_history.hpp"

namespace isk {

namespace detail {
struct DeviceFramePipeline;  // lib/src/frame_pipeline.hpp
}  // namespace detail

// How an implicit skinner is built and what each frame does.
struct ImplicitSkinnerOptions {
  // Samples per bone, grid resolution and precision, operators per joint,
  // progress, ...
  ImplicitFieldsOptions fields;
  // Rounds, sigma, contact angle, tolerance, relaxation, smoothing: the
  // paper's values by default.
  SurfaceTrackingOptions tracking;
  // The geometric skinning the march starts from.
  SkinningMethod base_skinning = SkinningMethod::kDualQuaternion;
  // Grid and operator table storage on the device.
  FieldStorage storage = FieldStorage::kAuto;
  // How each frame's march starts (isk/tracking/tracking_history.hpp): from
  // the base skinning (the 2013 paper) or from the last frame's result
  // moved by the skinning's motion. ImplicitCrowd takes the 2013 mode only.
  TrackingMode tracking_mode = TrackingMode::k2013;
  // History mode: a frame in which a joint turned by more than this
  // (degrees, relative to its parent) since the last frame starts from
  // skinning, as the first frame does. [0, 180].
  float history_reset_degrees = 30.f;
  // Each frame computed about its pose's anchor (isk/rig/pose_anchor.hpp),
  // so that where the character stands does not change its deformation.
  // Off: computed in the given coordinates, as ImplicitCrowd always does
  // (its instances share one scene).
  bool anchor_pose = true;

  // Names the first bad option (the fields' own options are validated by
  // buildImplicitFields).
  Validation validate() const;
};

// Milliseconds per stage of one frame (profiling events on OpenCL, host wall
// time on the CPU).
struct ImplicitStageTimes {
  double upload_ms = 0;         // joint transforms
  double skinning_ms = 0;       // base skinning
  TrackingStageTimes tracking;  // projection, relaxation, smoothing, normals
  double readback_ms = 0;       // last readPositions + readNormals
  // Sum of the stages.
  double total() const {
    return upload_ms + skinning_ms + tracking.total() + readback_ms;
  }
};

// Implicit skinning of one character on an OpenCL device (see the top of
// this file). Not copyable; movable.
class ImplicitSkinner {
 public:
  // Builds the rig's fields with options.fields and uploads. Throws
  // isk::Error: kInvalidArgument naming what is wrong in the rig or the
  // options, kOpenCl naming the failing call.
  ImplicitSkinner(std::shared_ptr<ClContext> context, const Rig& rig,
                  const ImplicitSkinnerOptions& options = {});
  // Uses fields built earlier for this rig (buildImplicitFields); shared
  // with other skinners (e.g. the CPU reference) without a copy.
  ImplicitSkinner(std::shared_ptr<ClContext> context, const Rig& rig,
                  std::shared_ptr<const ImplicitFields> fields,
                  const ImplicitSkinnerOptions& options = {});

  // One frame: #joints skinning transforms (isk/rig/pose.hpp). Returns when the
  // device is done. Throws isk::Error(kInvalidArgument) for a pose of the
  // wrong size or with non-finite transforms. In the history mode
  // (options.tracking_mode) the frame starts from the last one's result.
  void run(const TransformList& skinning);
  // History mode: the next frame starts from skinning (as the first does);
  // call it when the animation jumps (scrubbing, a cut). No effect in the
  // 2013 mode.
  void resetHistory();

  // Blocking reads of the last frame (#V by 3, model space; unit normals).
  // Throw isk::Error(kOpenCl) naming the call when the device fails.
  void readPositions(Matrix3Xf& out);
  void readNormals(Matrix3Xf& out);
  // The same results on the device: #V * 3 packed floats.
  const cl::Buffer& positionsBuffer() const;
  const cl::Buffer& normalsBuffer() const;
  // Vertices stopped at a contact in the last frame (reads the states).
  int contactCount();
  // The last frame's anchor (zero before the first run, with anchor_pose
  // off, or for a character near the origin). The parts below (skinning(),
  // tracking()) hold that frame with the anchor taken out of its pose.
  Eigen::Vector3f anchor() const;

  // Stage times of the last run() (readback: of the last reads).
  const ImplicitStageTimes& lastTimes() const;
  // What the skinner was built from, and its parts (for stage-by-stage use,
  // interop and tests). They throw isk::Error(kInvalidArgument) on a
  // moved-from skinner, as run() and the reads do (the reads also before
  // run()).
  const ImplicitFields& fields() const;
  const TrackingMesh& trackingMesh() const;
  ClSkinning& skinning();
  ClFieldEvaluation& fieldEvaluation();
  ClSurfaceTracking& tracking();
  const ImplicitSkinnerOptions& options() const { return options_; }
  ClContext& context();
  int vertexCount() const;  // #V

  ~ImplicitSkinner();
  ImplicitSkinner(ImplicitSkinner&&) noexcept;
  ImplicitSkinner& operator=(ImplicitSkinner&&) noexcept;

 private:
  // Throws isk::Error(kInvalidArgument) naming `what` on a moved-from
  // skinner, or before the first run() when `needs_run`; returns the frame
  // pipeline.
  detail::DeviceFramePipeline& usable(const char* what, bool needs_run) const;

  ImplicitSkinnerOptions options_;
  std::shared_ptr<const ImplicitFields> fields_;
  // The device parts, shared with ImplicitCrowd (lib/src/frame_pipeline.hpp);
  // held by pointer, so that moves keep the tracking's references valid.
  std::unique_ptr<detail::DeviceFramePipeline> pipeline_;
  ImplicitStageTimes no_times_;  // lastTimes() of a moved-from skinner
};

// The CPU reference of ImplicitSkinner (CpuSkinning + CpuSurfaceTracking):
// single thread, the same calls and results up to float rounding. Its
// options.storage is ignored.
class CpuImplicitSkinner {
 public:
  // As ImplicitSkinner's constructors, without a device. Throws
  // isk::Error(kInvalidArgument) naming what is wrong in the rig or options.
  CpuImplicitSkinner(const Rig& rig,
                     const ImplicitSkinnerOptions& options = {});
  CpuImplicitSkinner(const Rig& rig,
                     std::shared_ptr<const ImplicitFields> fields,
                     const ImplicitSkinnerOptions& options = {});

  // One frame: #joints skinning transforms. As ImplicitSkinner's:
  // isk::Error(kInvalidArgument) for a pose of the wrong size or with
  // non-finite transforms, a moved-from skinner, or a result asked for
  // before run().
  void run(const TransformList& skinning);
  void resetHistory();  // as ImplicitSkinner's
  // Results of the last frame: #V by 3, model space; unit normals.
  const Matrix3Xf& positions() const {
    checkUsable("positions", true);
    return tracking_->positions();
  }
  const Matrix3Xf& normals() const {
    checkUsable("normals", true);
    return tracking_->normals();
  }
  void readPositions(Matrix3Xf& out) const { out = positions(); }
  void readNormals(Matrix3Xf& out) const { out = normals(); }
  // Vertices stopped at a contact in the last frame.
  int contactCount() const;
  // As ImplicitSkinner's.
  Eigen::Vector3f anchor() const {
    checkUsable("anchor", false);
    return anchor_;
  }

  const ImplicitStageTimes& lastTimes() const { return times_; }
  const ImplicitFields& fields() const {
    checkUsable("fields", false);
    return *fields_;
  }
  const TrackingMesh& trackingMesh() const {
    checkUsable("trackingMesh", false);
    return *tracking_mesh_;
  }
  CpuSkinning& skinning() {
    checkUsable("skinning", false);
    return *skinning_;
  }
  CpuSurfaceTracking& tracking() {
    checkUsable("tracking", false);
    return *tracking_;
  }
  int vertexCount() const {  // #V
    checkUsable("vertexCount", false);
    return tracking_mesh_->vertexCount();
  }

 private:
  void checkUsable(const char* what, bool needs_run) const;

  ImplicitSkinnerOptions options_;
  std::shared_ptr<const ImplicitFields> fields_;
  std::unique_ptr<const TrackingMesh> tracking_mesh_;
  std::unique_ptr<CpuSkinning> skinning_;
  std::unique_ptr<CpuSurfaceTracking> tracking_;
  ImplicitStageTimes times_;
  bool has_run_ = false;
  // Anchoring (options_.anchor_pose): the joints' rest centres, the step,
  // the last frame's anchor and pose with the anchor taken out.
  std::vector<Eigen::Vector3f> anchor_centers_;
  float anchor_step_ = 1.f;
  Eigen::Vector3f anchor_ = Eigen::Vector3f::Zero();
  TransformList anchored_pose_;
  // History mode: when a frame starts from the last, and the last result
  // carried back to rest space (#V by 3).
  std::unique_ptr<TrackingHistory> history_;
  Matrix3Xf history_rest_, history_start_;
};

}  // namespace isk
