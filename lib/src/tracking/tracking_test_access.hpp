// What only the tests need of the trackings, kept out of their public API:
// replacing the working state, so that both backends run a stage from the
// same input and are compared stage by stage.
#pragma once

#include <vector>

#include "isk/cl/surface_tracking.hpp"
#include "isk/tracking/surface_tracking.hpp"

namespace isk::detail {

struct TrackingTestAccess {
  // After a begin() that set the pose; prev_gradients #V by 4 (xyz the
  // previous step's unit gradient, w what it was, ISK_GRADIENT_*),
  // relax_frames optional #V by 4 (CpuSurfaceTracking::relaxFrames).
  // Throws isk::Error(kInvalidArgument) before begin() or unless every
  // size is #V.
  template <typename Tracking>
  static void setState(Tracking& tracking, const Matrix3Xf& positions,
                       const std::vector<TrackState>& states,
                       const Matrix4Xf& prev_gradients,
                       const Matrix4Xf* relax_frames = nullptr) {
    tracking.setState(positions, states, prev_gradients, relax_frames);
  }
};

}  // namespace isk::detail
