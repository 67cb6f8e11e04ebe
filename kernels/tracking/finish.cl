// Surface tracking, the end of a frame: the results back in the mesh's
// vertex order, every seam copy taking its representative's position.
// OpenCL C 1.2. CPU reference: CpuSurfaceTracking::finish
// (lib/src/tracking/surface_tracking.cpp).

#include "common.h"

// Back to the mesh's order: vertex v takes the position at device index
// representative[v] (its own, or its seam representative's).
__kernel void track_copy_duplicates(const uint vertex_count,
                                    __global const int* representative,
                                    __global const float* positions_in,
                                    __global float* positions_out) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  vstore3(vload3(representative[v], positions_in), v, positions_out);
}

// The results moved by `offset` (x, y, z): a skinner tracks its frame about
// the pose's anchor and adds the anchor back (isk/rig/pose_anchor.hpp).
__kernel void track_translate(const uint vertex_count,
                              __global float* positions, const float x,
                              const float y, const float z) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  vstore3(vload3(v, positions) + (float3)(x, y, z), v, positions);
}
