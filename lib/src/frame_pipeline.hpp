// One implicit skinning frame on an OpenCL device, the same for one
// character (ImplicitSkinner) and for a crowd (ImplicitCrowd): geometric
// skinning (ClSkinning), then surface tracking in the composed fields
// (ClFieldEvaluation, ClSurfaceTracking; Vaillant et al. 2013, section 5),
// enqueued without a wait between them; the results stay on the device.
#pragma once

#include <memory>
#include <vector>

#include "isk/implicit_skinner.hpp"

namespace isk::detail {

struct DeviceFramePipeline {
  // Builds the device parts in pipeline order: skinning of `mesh` (#V) by
  // `weights` over `joints` joints, the field groups' evaluation, the
  // tracking of `tracking_mesh` (kept here: the tracking holds a reference).
  DeviceFramePipeline(
      std::shared_ptr<ClContext> context, const Mesh& mesh,
      const SkinWeights& weights, int joints,
      const std::vector<ClFieldEvaluation::FieldGroup>& field_groups,
      TrackingMesh tracking_mesh, const ImplicitSkinnerOptions& options);

  // One frame: #joints skinning transforms; returns when the device is
  // done, with `times` set.
  void run(const TransformList& skinning);
  // Frames computed about the pose's anchor (isk/rig/pose_anchor.hpp): one
  // character, its #joints rest centres and its anchor step.
  void enableAnchoring(std::vector<Eigen::Vector3f> rest_centers, float step);
  // History-dependent tracking from the next frame on (one character:
  // `parents` are its joints'; isk/tracking/tracking_history.hpp).
  void enableHistory(std::vector<int> parents);
  // Blocking reads of the last frame, timed into times.readback_ms.
  void readPositions(Matrix3Xf& out);
  void readNormals(Matrix3Xf& out);

  std::shared_ptr<ClContext> context;
  ImplicitSkinnerOptions options;
  std::unique_ptr<const TrackingMesh> tracking_mesh;
  std::unique_ptr<ClSkinning> skinning;
  std::unique_ptr<ClFieldEvaluation> field_evaluation;
  std::unique_ptr<ClSurfaceTracking> tracking;
  ImplicitStageTimes times;
  bool has_run = false;
  // Anchoring (off: the frame is computed in the given coordinates): the
  // joints' rest centres, the step, the last frame's anchor and pose with
  // the anchor taken out.
  bool anchoring = false;
  std::vector<Eigen::Vector3f> anchor_centers;
  float anchor_step = 1.f;
  Eigen::Vector3f anchor = Eigen::Vector3f::Zero();
  TransformList anchored_pose;
  // History mode (null: the 2013 mode): when a frame starts from the last,
  // the last result carried back to rest space and the start skinned from
  // it (#V * 3 floats each).
  std::unique_ptr<TrackingHistory> history;
  cl::Buffer history_rest, history_start;
};

}  // namespace isk::detail
