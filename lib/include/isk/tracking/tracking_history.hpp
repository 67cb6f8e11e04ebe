// History-dependent tracking (after Vaillant et al. 2014, "Robust
// Iso-Surface Tracking for Interactive Character Skinning"; see
// docs/algorithm.md "History-dependent tracking"): the vertices that the
// last frame stopped at a contact or in a crease start this frame from their
// last result moved by their incremental skinning motion -- carried back to
// rest space by the inverse of the last pose's blended transform
// (isk::unskinPoints), then skinned by this pose's -- instead of from
// skinning, and march from there to their rest iso values. Where skinning
// pushes skin deep through another part (a knee bent past 120 degrees), the
// last frame's contact is still on the right side of that part, a short
// step away. Every other vertex starts from skinning, as in the 2013 method,
// so that the skin returns to its rest shape once nothing presses on it.
// The first frame, a pose jump and an explicit reset start every vertex
// from skinning.
//
// This file holds the mode and the host's bookkeeping of when a frame may
// start from the last one; the skinners (isk/implicit_skinner.hpp) carry
// the positions, on the device or on the CPU.
#pragma once

#include <vector>

#include "isk/core/types.hpp"

namespace isk {

// How each frame's march starts.
enum class TrackingMode {
  k2013,     // from geometric skinning of the rest pose (the paper)
  kHistory,  // from the last frame's result, moved by the skinning's motion
};

// "2013" / "history".
const char* trackingModeName(TrackingMode mode);

// The largest turn, in degrees, of a joint relative to its parent between
// two poses (#joints skinning transforms each, `parents` #joints, -1 for
// roots): the angle of the rotation that takes the joint's rotation
// relative to its parent in `from` to the one in `to`. Roots are left out:
// a rigid motion of the whole character is carried exactly by the history.
float largestRelativeTurnDegrees(const std::vector<int>& parents,
                                 const TransformList& from,
                                 const TransformList& to);

// When a frame may start from the last one's result.
class TrackingHistory {
 public:
  // `parents`: #joints, -1 for roots; `reset_degrees`: a pose in which a
  // joint turned by more than this since the last frame starts from
  // skinning.
  TrackingHistory(std::vector<int> parents, float reset_degrees);

  // Whether the frame at `pose` starts from the last frame's result: false
  // on the first frame, after reset(), and on a pose jump. Records `pose`
  // as the last frame's.
  bool next(const TransformList& pose);
  // The next frame starts from skinning.
  void reset() { has_last_ = false; }

 private:
  std::vector<int> parents_;
  float reset_degrees_;
  TransformList last_;
  bool has_last_ = false;
};

}  // namespace isk
