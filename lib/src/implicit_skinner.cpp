#include "isk/implicit_skinner.hpp"

#include <chrono>
#include <string>

#include "isk/core/error.hpp"
#include "skinner_fields.hpp"
#include "isk/core/stopwatch.hpp"

namespace isk {

namespace {

std::shared_ptr<const ImplicitFields> checkedFields(
    const Rig& rig, std::shared_ptr<const ImplicitFields> fields) {
  if (!fields)
    throw Error(ErrorCode::kInvalidArgument, "implicit skinner: no fields");
  if (const Validation v = fieldsFitRig(*fields, rig); !v)
    throw Error(ErrorCode::kInvalidArgument, "implicit skinner: " + v.reason());
  return fields;
}

}  // namespace

Validation ImplicitSkinnerOptions::validate() const {
  if (const Validation v = tracking.validate(); !v)
    return Validation::fail("tracking: " + v.reason());
  return Validation::ok();
}

ImplicitSkinner::ImplicitSkinner(std::shared_ptr<ClContext> context,
                                 const Rig& rig,
                                 const ImplicitSkinnerOptions& options)
    : ImplicitSkinner(std::move(context), rig,
                      detail::buildSkinnerFields(rig, options), options) {}

ImplicitSkinner::ImplicitSkinner(std::shared_ptr<ClContext> context,
                                 const Rig& rig,
                                 std::shared_ptr<const ImplicitFields> fields,
                                 const ImplicitSkinnerOptions& options)
    : context_(std::move(context)),
      options_(options),
      fields_(checkedFields(rig, std::move(fields))) {
  if (!context_)
    throw Error(ErrorCode::kInvalidArgument, "ImplicitSkinner: no context");
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  rig.validate().throwIfFailed(rig.source);
  tracking_mesh_ = std::make_unique<const TrackingMesh>(
      TrackingMesh::build(rig.mesh, *fields_));
  const int joints = rig.skeleton.jointCount();
  skinning_ =
      std::make_unique<ClSkinning>(context_, rig.mesh, rig.weights, joints);
  field_evaluation_ = std::make_unique<ClFieldEvaluation>(
      context_, fields_->grids, joints, options.storage, &fields_->composition);
  tracking_ = std::make_unique<ClSurfaceTracking>(
      *field_evaluation_, *tracking_mesh_, options.tracking);
}

void ImplicitSkinner::checkUsable(const char* what, bool needs_run) const {
  if (!tracking_)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ImplicitSkinner::") + what +
                    ": the skinner was moved from (it holds no rig)");
  if (needs_run && !has_run_)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ImplicitSkinner::") + what +
                    " before run(): there is no frame yet");
}

void ImplicitSkinner::run(const TransformList& skinning) {
  checkUsable("run", false);
  times_ = {};
  // Tracking is enqueued behind the skinning without a wait between them.
  skinning_->enqueue(options_.base_skinning, skinning,
                     /*recompute_normals=*/false);
  tracking_->run(skinning, skinning_->positionsBuffer(),
                 skinning_->normalsBuffer());
  skinning_->collectTimes();
  times_.upload_ms =
      skinning_->lastTimes().upload_ms + field_evaluation_->lastUploadMs();
  times_.skinning_ms = skinning_->lastTimes().skinning_ms;
  times_.tracking = tracking_->lastTimes();
  has_run_ = true;
}

void ImplicitSkinner::readPositions(Matrix3Xf& out) {
  checkUsable("readPositions", true);
  const auto start = std::chrono::steady_clock::now();
  tracking_->readPositions(out);
  times_.readback_ms += millisecondsSince(start);
}

void ImplicitSkinner::readNormals(Matrix3Xf& out) {
  checkUsable("readNormals", true);
  const auto start = std::chrono::steady_clock::now();
  tracking_->readNormals(out);
  times_.readback_ms += millisecondsSince(start);
}

const cl::Buffer& ImplicitSkinner::positionsBuffer() const {
  checkUsable("positionsBuffer", false);
  return tracking_->positionsBuffer();
}
const cl::Buffer& ImplicitSkinner::normalsBuffer() const {
  checkUsable("normalsBuffer", false);
  return tracking_->normalsBuffer();
}
int ImplicitSkinner::contactCount() {
  checkUsable("contactCount", true);
  return tracking_->contactCount();
}

CpuImplicitSkinner::CpuImplicitSkinner(const Rig& rig,
                                       const ImplicitSkinnerOptions& options)
    : CpuImplicitSkinner(rig, detail::buildSkinnerFields(rig, options),
                         options) {}

CpuImplicitSkinner::CpuImplicitSkinner(
    const Rig& rig, std::shared_ptr<const ImplicitFields> fields,
    const ImplicitSkinnerOptions& options)
    : options_(options), fields_(checkedFields(rig, std::move(fields))) {
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  rig.validate().throwIfFailed(rig.source);
  tracking_mesh_ = std::make_unique<const TrackingMesh>(
      TrackingMesh::build(rig.mesh, *fields_));
  skinning_ = std::make_unique<CpuSkinning>(rig.mesh, rig.weights,
                                            rig.skeleton.jointCount());
  tracking_ = std::make_unique<CpuSurfaceTracking>(
      fields_->grids, &fields_->composition, *tracking_mesh_, options.tracking);
}

void CpuImplicitSkinner::checkUsable(const char* what, bool needs_run) const {
  if (!tracking_)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("CpuImplicitSkinner::") + what +
                    ": the skinner was moved from (it holds no rig)");
  if (needs_run && !has_run_)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("CpuImplicitSkinner::") + what +
                    " before run(): there is no frame yet");
}

void CpuImplicitSkinner::run(const TransformList& skinning) {
  checkUsable("run", false);
  times_ = {};
  skinning_->run(options_.base_skinning, skinning,
                 /*recompute_normals=*/false);
  tracking_->run(skinning, skinning_->positions(), skinning_->normals());
  times_.skinning_ms = skinning_->lastTimes().skinning_ms;
  times_.tracking = tracking_->lastTimes();
  has_run_ = true;
}

int CpuImplicitSkinner::contactCount() const {
  checkUsable("contactCount", true);
  return countStates(tracking_->states()).contact;
}

}  // namespace isk
