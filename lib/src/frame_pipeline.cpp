#include "frame_pipeline.hpp"

#include <chrono>

#include "isk/core/stopwatch.hpp"

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

void DeviceFramePipeline::run(const TransformList& pose) {
  times = {};
  // Tracking is enqueued behind the skinning without a wait between them.
  skinning->enqueue(options.base_skinning, pose, /*recompute_normals=*/false);
  tracking->run(pose, skinning->positionsBuffer(), skinning->normalsBuffer());
  skinning->collectTimes();
  times.upload_ms =
      skinning->lastTimes().upload_ms + field_evaluation->lastUploadMs();
  times.skinning_ms = skinning->lastTimes().skinning_ms;
  times.tracking = tracking->lastTimes();
  has_run = true;
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
