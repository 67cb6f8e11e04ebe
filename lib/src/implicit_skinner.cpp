#include "isk/implicit_skinner.hpp"

#include <chrono>
#include <string>

#include "frame_pipeline.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/rig/pose_anchor.hpp"
#include "skinner_fields.hpp"
#include "usability.hpp"

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

std::vector<int> jointParents(const Skeleton& skeleton) {
  std::vector<int> parents;
  for (const Joint& joint : skeleton.joints) parents.push_back(joint.parent);
  return parents;
}

}  // namespace

Validation ImplicitSkinnerOptions::validate() const {
  if (const Validation v = tracking.validate(); !v)
    return Validation::fail("tracking: " + v.reason());
  if (!(history_reset_degrees >= 0.f && history_reset_degrees <= 180.f))
    return Validation::fail("history_reset_degrees is " +
                            std::to_string(history_reset_degrees) +
                            ": expected 0 to 180");
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
    : options_(options), fields_(checkedFields(rig, std::move(fields))) {
  if (!context)
    throw Error(ErrorCode::kInvalidArgument, "ImplicitSkinner: no context");
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  rig.validate().throwIfFailed(rig.source);
  const int joints = rig.skeleton.jointCount();
  pipeline_ = std::make_unique<detail::DeviceFramePipeline>(
      std::move(context), rig.mesh, rig.weights, joints,
      std::vector<ClFieldEvaluation::FieldGroup>{
          {&fields_->grids, joints, &fields_->composition, 1}},
      detail::buildSkinnerTrackingMesh(rig, *fields_), options);
  if (options.anchor_pose)
    pipeline_->enableAnchoring(restCenters(rig.mesh.positions, joints),
                               anchorStep(rig.boundingBoxDiagonal()));
  if (options.tracking_mode == TrackingMode::kHistory)
    pipeline_->enableHistory(jointParents(rig.skeleton));
}

ImplicitSkinner::~ImplicitSkinner() = default;
ImplicitSkinner::ImplicitSkinner(ImplicitSkinner&&) noexcept = default;
ImplicitSkinner& ImplicitSkinner::operator=(ImplicitSkinner&&) noexcept =
    default;

detail::DeviceFramePipeline& ImplicitSkinner::usable(const char* what,
                                                     bool needs_run) const {
  detail::checkUsable("ImplicitSkinner", "skinner", what, pipeline_ != nullptr,
                      needs_run, pipeline_ && pipeline_->has_run);
  return *pipeline_;
}

void ImplicitSkinner::run(const TransformList& skinning) {
  usable("run", false).run(skinning);
}
void ImplicitSkinner::resetHistory() {
  if (TrackingHistory* history = usable("resetHistory", false).history.get())
    history->reset();
}
void ImplicitSkinner::readPositions(Matrix3Xf& out) {
  usable("readPositions", true).readPositions(out);
}
void ImplicitSkinner::readNormals(Matrix3Xf& out) {
  usable("readNormals", true).readNormals(out);
}
const cl::Buffer& ImplicitSkinner::positionsBuffer() const {
  return usable("positionsBuffer", false).tracking->positionsBuffer();
}
const cl::Buffer& ImplicitSkinner::normalsBuffer() const {
  return usable("normalsBuffer", false).tracking->normalsBuffer();
}
int ImplicitSkinner::contactCount() {
  return usable("contactCount", true).tracking->contactCount();
}
Eigen::Vector3f ImplicitSkinner::anchor() const {
  return usable("anchor", false).anchor;
}
const ImplicitStageTimes& ImplicitSkinner::lastTimes() const {
  return pipeline_ ? pipeline_->times : no_times_;
}
const ImplicitFields& ImplicitSkinner::fields() const {
  usable("fields", false);
  return *fields_;
}
const TrackingMesh& ImplicitSkinner::trackingMesh() const {
  return *usable("trackingMesh", false).tracking_mesh;
}
ClSkinning& ImplicitSkinner::skinning() {
  return *usable("skinning", false).skinning;
}
ClFieldEvaluation& ImplicitSkinner::fieldEvaluation() {
  return *usable("fieldEvaluation", false).field_evaluation;
}
ClSurfaceTracking& ImplicitSkinner::tracking() {
  return *usable("tracking", false).tracking;
}
ClContext& ImplicitSkinner::context() {
  return *usable("context", false).context;
}
int ImplicitSkinner::vertexCount() const {
  return usable("vertexCount", false).tracking_mesh->vertexCount();
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
      detail::buildSkinnerTrackingMesh(rig, *fields_));
  skinning_ = std::make_unique<CpuSkinning>(rig.mesh, rig.weights,
                                            rig.skeleton.jointCount());
  tracking_ = std::make_unique<CpuSurfaceTracking>(
      fields_->grids, &fields_->composition, *tracking_mesh_, options.tracking);
  if (options.anchor_pose) {
    anchor_centers_ =
        restCenters(rig.mesh.positions, rig.skeleton.jointCount());
    anchor_step_ = anchorStep(rig.boundingBoxDiagonal());
  }
  if (options.tracking_mode == TrackingMode::kHistory)
    history_ = std::make_unique<TrackingHistory>(jointParents(rig.skeleton),
                                                 options.history_reset_degrees);
}

void CpuImplicitSkinner::checkUsable(const char* what, bool needs_run) const {
  detail::checkUsable("CpuImplicitSkinner", "skinner", what,
                      tracking_ != nullptr, needs_run, has_run_);
}

void CpuImplicitSkinner::run(const TransformList& given_skinning) {
  checkUsable("run", false);
  times_ = {};
  // Empty centres (anchor_pose off) give anchor zero.
  anchor_ = poseAnchor(given_skinning, anchor_centers_, anchor_step_);
  const bool moved = !anchor_.isZero();
  if (moved) {
    anchored_pose_ = given_skinning;
    subtractAnchor(anchor_, anchored_pose_);
  }
  const TransformList& skinning = moved ? anchored_pose_ : given_skinning;
  skinning_->run(options_.base_skinning, skinning,
                 /*recompute_normals=*/false);
  const bool from_history = history_ && history_->next(skinning);
  if (from_history) {
    Matrix3Xf unused_normals;
    const SkinningJob job{
        options_.base_skinning, &history_rest_, &skinning_->restNormals(),
        &skinning_->weights(),  &skinning,      &history_start_,
        &unused_normals};
    job.run();
  }
  tracking_->run(skinning, skinning_->positions(), skinning_->normals(),
                 from_history ? &history_start_ : nullptr);
  if (history_)
    unskinPoints(options_.base_skinning, skinning_->weights(), skinning,
                 tracking_->positions(), history_rest_);
  if (moved) tracking_->translate(anchor_);
  times_.skinning_ms = skinning_->lastTimes().skinning_ms;
  times_.tracking = tracking_->lastTimes();
  has_run_ = true;
}

void CpuImplicitSkinner::resetHistory() {
  checkUsable("resetHistory", false);
  if (history_) history_->reset();
}

int CpuImplicitSkinner::contactCount() const {
  checkUsable("contactCount", true);
  return countStates(tracking_->states()).contact;
}

}  // namespace isk
