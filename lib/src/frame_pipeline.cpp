#include "frame_pipeline.hpp"

#include <algorithm>
#include <chrono>

#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/rig/pose_anchor.hpp"

namespace isk::detail {

DeviceFramePipeline::DeviceFramePipeline(
    std::shared_ptr<ClContext> context_in, const Mesh& mesh,
    const SkinWeights& weights, int joints,
    const std::vector<ClFieldEvaluation::FieldGroup>& field_groups,
    TrackingMesh tracking_mesh_in, const ImplicitSkinnerOptions& options_in)
    : context(std::move(context_in)),
      options(options_in),
      tracking_mesh(
          std::make_unique<const TrackingMesh>(std::move(tracking_mesh_in))) {
  skinning = std::make_unique<ClSkinning>(context, mesh, weights, joints);
  field_evaluation = std::make_unique<ClFieldEvaluation>(context, field_groups,
                                                         options.storage);
  tracking = std::make_unique<ClSurfaceTracking>(
      *field_evaluation, *tracking_mesh, options.tracking);
}

void DeviceFramePipeline::run(const TransformList& given_pose) {
  times = {};
  anchor = anchoring ? poseAnchor(given_pose, anchor_centers, anchor_step)
                     : Eigen::Vector3f::Zero();
  const bool moved = !anchor.isZero();
  if (moved) {
    anchored_pose = given_pose;
    subtractAnchor(anchor, anchored_pose);
  }
  const TransformList& pose = moved ? anchored_pose : given_pose;
  // Tracking is enqueued behind the skinning without a wait between them.
  skinning->enqueue(options.base_skinning, pose, /*recompute_normals=*/false);
  const bool from_history = history && history->next(pose);
  if (from_history) skinning->enqueueSkinPoints(history_rest, history_start);
  tracking->run(pose, skinning->positionsBuffer(), skinning->normalsBuffer(),
                from_history ? &history_start : nullptr);
  if (history) {
    skinning->enqueueUnskinPoints(tracking->positionsBuffer(), history_rest);
    try {
      context->queue().finish();
    } catch (const cl::Error& e) {
      throwClError(e, "ImplicitSkinner: carrying the frame back to rest on " +
                          context->info().describe());
    }
  }
  if (moved) tracking->translate(anchor);
  skinning->collectTimes();
  times.upload_ms =
      skinning->lastTimes().upload_ms + field_evaluation->lastUploadMs();
  times.skinning_ms = skinning->lastTimes().skinning_ms;
  times.tracking = tracking->lastTimes();
  has_run = true;
}

void DeviceFramePipeline::enableAnchoring(
    std::vector<Eigen::Vector3f> rest_centers, float step) {
  anchoring = true;
  anchor_centers = std::move(rest_centers);
  anchor_step = step;
}

void DeviceFramePipeline::enableHistory(std::vector<int> parents) {
  history = std::make_unique<TrackingHistory>(std::move(parents),
                                              options.history_reset_degrees);
  const size_t bytes =
      3 * sizeof(float) *
      static_cast<size_t>(std::max(skinning->vertexCount(), 1));
  history_rest = context->createBuffer(CL_MEM_READ_WRITE, bytes, nullptr,
                                       "ImplicitSkinner history (rest space)");
  history_start = context->createBuffer(CL_MEM_READ_WRITE, bytes, nullptr,
                                        "ImplicitSkinner history start");
}

void DeviceFramePipeline::readPositions(Matrix3Xf& out) {
  const auto start = std::chrono::steady_clock::now();
  tracking->readPositions(out);
  times.readback_ms += millisecondsSince(start);
}

void DeviceFramePipeline::readNormals(Matrix3Xf& out) {
  const auto start = std::chrono::steady_clock::now();
  tracking->readNormals(out);
  times.readback_ms += millisecondsSince(start);
}

}  // namespace isk::detail
