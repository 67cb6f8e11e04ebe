// Geometric skinning and vertex normals on an OpenCL device.
//
// Host class of kernels/skinning.cl and kernels/normals.cl: uploads a mesh's
// static data once, then per frame uploads only the joint transforms, runs
// the skinning kernel (LBS or DQS) and the normals kernel, and leaves the
// results in device buffers (read them back, or hand the buffers to your
// renderer). Results match the CPU reference (isk/skinning/skinning.hpp and
// isk/core/vertex_normals.hpp, together in isk/skinning/cpu_skinning.hpp) up to
// float rounding.
#pragma once

#include <memory>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/core/mesh.hpp"
#include "isk/core/types.hpp"
#include "isk/rig/skin_weights.hpp"
#include "isk/skinning/skinning.hpp"

namespace isk {

// Errors: every call throws isk::Error(kOpenCl) naming the OpenCL call when
// the device fails; run() and enqueue() throw kInvalidArgument for a pose of
// the wrong size or with non-finite transforms.
class ClSkinning {
 public:
  // Validates the mesh and weights (isk::Error kInvalidArgument) and uploads
  // them; `joint_count` is the length of the transform lists run() takes.
  ClSkinning(std::shared_ptr<ClContext> context, const Mesh& mesh,
             const SkinWeights& weights, int joint_count);

  // Skins the rest mesh with `skinning` (#joints transforms) and, when asked,
  // recomputes area-weighted normals from the skinned positions; otherwise
  // the normals are the skinned rest normals. Returns when the device is done
  // (so that lastTimes() holds this frame's stage times).
  void run(SkinningMethod method, const TransformList& skinning,
           bool recompute_normals = true);
  // The same without waiting when the queue has profiling (later commands
  // on the queue may follow at once, as the implicit skinner's tracking
  // does); collectTimes() then waits for the frame's skinning and fills
  // lastTimes(). Without profiling it is run().
  void enqueue(SkinningMethod method, const TransformList& skinning,
               bool recompute_normals = true);
  // Waits for the last enqueue() and fills lastTimes().
  void collectTimes();

  // After enqueue(), with its method and transforms (enqueued, not waited
  // for; #V * 3 packed floats each). skinPoints: skins `rest_points` in
  // place of the rest mesh into `out` (no normals). unskinPoints: carries
  // `posed` back to rest space into `out_rest` (isk::unskinPoints).
  // History-dependent tracking keeps its vertices in rest space between
  // frames with them. Throw isk::Error(kInvalidArgument) before the first
  // enqueue() or for buffers smaller than #V vertices.
  void enqueueSkinPoints(const cl::Buffer& rest_points, const cl::Buffer& out);
  void enqueueUnskinPoints(const cl::Buffer& posed, const cl::Buffer& out_rest);

  // Blocking reads of the last run's results (#V by 3). Throw
  // isk::Error(kInvalidArgument) before the first run() and on a moved-from
  // object, as run() does.
  void readPositions(Matrix3Xf& out);
  void readNormals(Matrix3Xf& out);

  // Device buffers of the last results: #V * 3 floats (x y z per vertex).
  const cl::Buffer& positionsBuffer() const { return out_positions_; }
  const cl::Buffer& normalsBuffer() const { return out_normals_; }

  // Stage times of the last run and reads: from profiling events when the
  // queue has profiling, else host wall time around finished commands.
  const SkinningStageTimes& lastTimes() const { return times_; }
  ClContext& context() { return *context_; }
  const ClContext& context() const { return *context_; }
  // #V of the uploaded mesh.
  int vertexCount() const { return vertex_count_; }

 private:
  // Throws isk::Error(kInvalidArgument) naming `what` on a moved-from
  // object, or before the first run when `needs_run`.
  void checkUsable(const char* what, bool needs_run) const;
  // Blocking read of a #V by 3 result; returns its milliseconds.
  double readBuffer(const cl::Buffer& buffer, Matrix3Xf& out, const char* what);

  std::shared_ptr<ClContext> context_;
  int vertex_count_ = 0;
  int joint_count_ = 0;
  cl::Kernel lbs_kernel_, dqs_kernel_, triangle_normals_kernel_,
      normals_kernel_, unskin_lbs_kernel_, unskin_dqs_kernel_;
  // Throws isk::Error(kInvalidArgument) naming `what` when `buffer` holds
  // fewer than #V packed vertices.
  void checkVertexBuffer(const cl::Buffer& buffer, const char* what) const;
  cl::Buffer rest_positions_, rest_normals_;
  cl::Buffer influence_offsets_, influence_joints_, influence_weights_;
  // The triangles (#F by 3), their cross products of the frame (#F by 3
  // floats) and the vertex -> triangle rows (VertexTriangleAdjacency).
  int triangle_count_ = 0;
  cl::Buffer triangles_, triangle_normals_;
  cl::Buffer adjacency_offsets_, adjacency_triangles_;
  cl::Buffer joint_transforms_;
  std::vector<float> staging_;  // packed joint transforms of the last run
  cl::Buffer skinned_normals_, out_positions_, out_normals_;
  // enqueueSkinPoints' normals, written and not used (made on first use).
  cl::Buffer point_normals_;
  SkinningMethod method_ = SkinningMethod::kDualQuaternion;  // of enqueue()
  SkinningStageTimes times_;
  // Of enqueue(); the normals' two launches.
  cl::Event upload_event_, skin_event_, triangle_normals_event_, normals_event_;
  bool pending_ = false, pending_normals_ = false;
  bool has_run_ = false;  // a frame was enqueued: results can be read
};

}  // namespace isk
