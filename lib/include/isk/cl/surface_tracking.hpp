// Surface tracking on an OpenCL device: host class of kernels/tracking/
// (projection with the contact stop, tangential relaxation, beta diffusion,
// localized Laplacian smoothing) and of kernels/normals.cl.
//
// Same job, stages and formulas as the CPU reference isk::CpuSurfaceTracking
// (isk/tracking/surface_tracking.hpp, where they are documented). Every buffer
// stays on the device: a frame uploads nothing but the pose (through the field
// evaluation's setPose), starts from skinned positions already on the device
// (isk::ClSkinning's buffers) and leaves its results in positionsBuffer() and
// normalsBuffer(). The per-vertex state (marching, converged, contact, lost,
// untracked) and the previous gradients live on the device between stages,
// in the device's vertex order (the tracked vertices in march order first:
// the projection reads them in sequence); the reads and setState() take
// and give the mesh's order, and finish() leaves the results in it.
#pragma once

#include <memory>
#include <vector>

#include "isk/cl/field_evaluation.hpp"
#include "isk/cl/runtime.hpp"
#include "isk/tracking/surface_tracking.hpp"

namespace isk {

namespace detail {
struct TrackingDeviceLayout;  // lib/src/cl/tracking_layout.hpp
}  // namespace detail

// One character's surface tracking on an OpenCL device (see above).
class ClSurfaceTracking {
 public:
  // `fields` (kept by reference, must outlive this) evaluates the
  // character's composed field on the same context; `mesh` is uploaded and
  // kept by reference too (each pose reads its partner pairs).
  // Throws isk::Error: kInvalidArgument for bad options or a mesh of another
  // size, kOpenCl naming the failing call.
  ClSurfaceTracking(ClFieldEvaluation& fields, const TrackingMesh& mesh,
                    const SurfaceTrackingOptions& options = {});

  // Stage by stage, as CpuSurfaceTracking (enqueued, not waited for). The
  // other stages and the reads throw isk::Error(kInvalidArgument) before the
  // first begin().
  // begin: the frame's pose (#joints) and the skinned positions and normals
  // on the device (#V * 3 packed floats each; normals are the fallback of
  // the normals stage); `start`, when given, the positions the vertices at
  // a contact or in a crease in the last frame start from (#V * 3 floats;
  // see CpuSurfaceTracking::begin).
  void begin(const TransformList& skinning, const cl::Buffer& skinned_positions,
             const cl::Buffer& skinned_normals,
             const cl::Buffer* start = nullptr);
  void project(int steps);    // `steps` projection steps (eq. 4)
  void relax();               // one relaxation step (eq. 5, 6)
  void smooth();              // beta, its diffusion and the Laplacian steps
  void restoreVolume();       // volume restoration (after smooth())
  void limitStrain();         // the strain limit's steps, with the fold guard
  void restoreVolumeAgain();  // the restoration and restore_again_steps more
                              // steps of the limit (after limitStrain())
  void finish();              // seam copies and normals

  // The whole frame; returns when the device is done, with lastTimes().
  // Stage calls and reads throw isk::Error(kOpenCl) naming the OpenCL call
  // when the device fails; begin() and run() throw kInvalidArgument for a
  // pose of the wrong size.
  void run(const TransformList& skinning, const cl::Buffer& skinned_positions,
           const cl::Buffer& skinned_normals,
           const cl::Buffer* start = nullptr);
  // After run(): the positions moved by `offset` (a skinner adds its pose's
  // anchor back, isk/rig/pose_anchor.hpp); returns when the device is done,
  // its time added to lastTimes()'s normals.
  void translate(const Eigen::Vector3f& offset);

  // Blocking reads of the working state and of the results.
  void readPositions(Matrix3Xf& out);  // working positions (results after
                                       // finish())
  void readNormals(Matrix3Xf& out);
  void readStates(std::vector<TrackState>& out);
  void readBeta(std::vector<float>& out);  // beta, gamma per vertex
  void readPreviousGradients(Matrix4Xf& out);
  void readRelaxFrames(Matrix4Xf& out);
  // Volume restoration's last run: lambda per group, and each vertex's
  // weight (#V, 0 outside the groups) as CpuSurfaceTracking's.
  void readVolumeFractions(std::vector<float>& out);
  void readRestoreWeights(std::vector<float>& out);
  // The contact bulge's last run: kappa per group, each vertex's band and
  // weight (#V) as CpuSurfaceTracking's (0 with the bulge off or not
  // needed).
  void readBulgeFractions(std::vector<float>& out);
  void readBulgeBand(std::vector<float>& out);
  void readBulgeWeights(std::vector<float>& out);
  // The fold guard's last check: each vertex's weight (#V) as
  // CpuSurfaceTracking::foldWeights() (0 without the guard).
  void readFoldWeights(std::vector<float>& out);
  // Vertices stopped at a contact in the last frame (a blocking read of the
  // states).
  int contactCount();

  // Device buffers of the results (#V * 3 packed floats), valid after
  // finish() / run().
  const cl::Buffer& positionsBuffer() const { return positions_[current_]; }
  const cl::Buffer& normalsBuffer() const { return normals_; }

  // Milliseconds per stage of the last run() (profiling events).
  const TrackingStageTimes& lastTimes() const { return times_; }
  const SurfaceTrackingOptions& options() const { return options_; }
  int vertexCount() const { return vertex_count_; }  // #V of the mesh
  // Device memory of the tracking's own buffers.
  size_t bytes() const { return bytes_; }

 private:
  // Uploads a working state (the tests, through detail::TrackingTestAccess:
  // both backends from the same input).
  friend struct detail::TrackingTestAccess;
  void setState(const Matrix3Xf& positions,
                const std::vector<TrackState>& states,
                const Matrix4Xf& prev_gradients,
                const Matrix4Xf* relax_frames = nullptr);

  enum Stage {
    kProjection,
    kRelaxation,
    kSmoothing,
    kVolume,
    kStrainLimit,
    kNormals
  };
  // Over `items` work-items (-1: one per vertex).
  void launch(cl::Kernel& kernel, Stage stage, int items = -1);
  void limitStrainSteps(int steps);  // limitStrain() with `steps` steps
  // One fold check of the strain limit's steps on `offsets` (all: every
  // triangle and vertex, else what changed since the last check); the
  // vertices whose weight changed and their ring are marked in `active`.
  void checkFolds(const cl::Buffer& offsets, bool all,
                  const cl::Buffer& active);
  void restoreVolumeWith(bool contact_bulge);  // restoreVolume()'s work
  void addTime(Stage stage, double ms);
  void collectTimes();
  // Binds kernels/tracking/project.cl's ISK_TRACKING_PARAMS from first_index
  // on.
  void setContactArgs(cl::Kernel& kernel, cl_uint first_index) const;
  void readFloats(const cl::Buffer& buffer, void* out, size_t bytes,
                  const char* what);
  // A float per vertex in the device's order, read into the mesh's.
  void readByVertex(const cl::Buffer& buffer, std::vector<float>& out,
                    const char* what);
  // Throws isk::Error(kInvalidArgument) naming `stage` before begin().
  void checkBegun(const char* stage) const;
  bool begun_ = false;

  // The constructor's steps: the programs and kernels; the tracking mesh in
  // the device's order (detail::trackingDeviceLayout, built on the host);
  // the broad phase's buffers, which each pose fills; the per-vertex state.
  void buildKernels(const ClFieldEvaluation& fields);
  void uploadLayout(const detail::TrackingDeviceLayout& layout);
  void allocateBroadPhase(const TrackingMesh& mesh);
  void allocateState(const TrackingMesh& mesh);

  ClFieldEvaluation* fields_;
  std::shared_ptr<ClContext> context_;
  SurfaceTrackingOptions options_;
  const TrackingMesh* mesh_;
  std::vector<int> partners_staging_;       // activePartners of the last pose
  std::vector<int> crease_shifts_staging_;  // restCreaseShifts of it
  FieldNeighbourhoods neighbourhoods_;      // of the last pose (staging)
  size_t neighbour_entry_capacity_ = 0;     // ints in neighbour_entries_
  // Cells per axis of the neighbourhoods' split: kCpuCellsPerAxis on a CPU
  // device, 1 (no split) on others.
  static constexpr int kCpuCellsPerAxis = 4;
  int cells_per_axis_ = 1;
  // The lane tests (the tuning's lane_tests, on a CPU device): per home field
  // its neighbourhood's fields in chunks of 8 lanes, built and uploaded at
  // each pose by buildLanes (layout: kernels/tracking/project.cl,
  // ISK_LANE_TESTS).
  bool lane_tests_ = false;
  void buildLanes();
  std::vector<int> lane_offsets_staging_;  // read by non-blocking writes
  std::vector<float> lane_params_staging_;
  std::vector<uint8_t> lane_masks_staging_;
  size_t lane_chunk_capacity_ = 0;  // chunks lane_params_ holds
  cl::Buffer lane_offsets_, lane_params_, lane_masks_;
  int vertex_count_ = 0;
  cl::Kernel begin_, project_, relax_, beta_init_, beta_diffuse_, smooth_,
      limit_strain_, strain_offsets_, strain_positions_, fold_frames_kernel_,
      weigh_triangles_, weigh_folds_, grow_folds_, commit_folds_,
      copy_duplicates_, translate_, triangle_normals_kernel_, normals_kernel_,
      volume_chunks_, restore_weights_, restore_weighted_, restore_fractions_,
      restore_apply_, restore_correct_, untrack_, bulge_band_init_,
      bulge_band_grow_, bulge_clearance_, bulge_weights_,
      bulge_fractions_kernel_;
  cl::Buffer every_cell_;  // tuning's occupied_cells off: all bits set
  cl::Buffer iso_values_, representative_, rules_, kinds_, home_fields_,
      home_margins_, home_floors_, rest_creases_, crease_shifts_, partners_,
      neighbour_offsets_, neighbour_entries_, neighbour_pair_offsets_,
      neighbour_pairs_, ring_offsets_, ring_neighbours_, ring_weights_,
      ring_lengths_, normal_offsets_, normal_triangles_;
  // The mesh's triangles (#F by 3) and their cross products of the frame.
  int triangle_count_ = 0;
  cl::Buffer triangles_, triangle_normals_;
  // The one-rings filtered to the neighbours within each vertex's smoothing
  // radius (rest distance), in ring order (diffusion, Laplacian steps).
  cl::Buffer near_offsets_, near_neighbours_;
  // Per vertex the near neighbours' mean rest length, and gamma's source
  // value of the frame (the crease gate).
  cl::Buffer near_mean_lengths_, crease_sources_;
  // Their transpose (active vertices: where a vertex pushes its reach),
  // and per vertex the first diffusion step it is in reach of (uchar).
  cl::Buffer reverse_offsets_, reverse_neighbours_, reach_;
  // trackingLengths per vertex: (max step, min gradient).
  cl::Buffer step_limits_;
  // The device's vertex order (see the constructor): order_[k] is the
  // mesh's vertex at device index k; the first march_count_ are the
  // tracked vertices in march order.
  std::vector<int> order_;
  int march_count_ = 0;
  // The dislocation guard: each mesh vertex's device index (the inverse of
  // order_), and the device indices of the vertices the pose dislocates
  // (staging read by a non-blocking write; buffer sized for every
  // candidate).
  std::vector<int> device_index_;
  std::vector<int> dislocated_staging_;
  cl::Buffer dislocated_;
  cl::Buffer begin_source_, finish_source_;  // order_; slot of representative
  bool user_order_ = false;  // positions_[current_] in the mesh's order
  // Rows in the mesh's order <-> rows in the device's order.
  template <typename Matrix>
  Matrix toDevice(const Matrix& by_vertex) const {
    Matrix out(by_vertex.rows(), by_vertex.cols());
    for (Eigen::Index k = 0; k < out.rows(); ++k)
      out.row(k) = by_vertex.row(order_[k]);
    return out;
  }
  template <typename Matrix>
  Matrix fromDevice(const Matrix& by_device) const {
    Matrix out(by_device.rows(), by_device.cols());
    for (Eigen::Index k = 0; k < out.rows(); ++k)
      out.row(order_[k]) = by_device.row(k);
    return out;
  }
  cl::Buffer positions_[2];
  int current_ = 0;
  cl::Buffer states_, prev_gradients_, relax_frames_, beta_[2], normals_;
  int beta_current_ = 0;          // beta_[beta_current_]: the last diffusion's
  cl::Buffer fallback_normals_;   // begin's skinned normals (a handle)
  cl::Buffer skinned_positions_;  // begin's skinned positions (a handle)
  // The strain limit's offsets (float triples) and active marks (uchar per
  // vertex), ping-pong; the rings' transpose (tracking_layout.hpp).
  cl::Buffer strain_offsets_buffers_[2], strain_active_[2];
  cl::Buffer ring_reverse_offsets_, ring_reverse_neighbours_;
  // The fold guard: the layout's fold rows (TrackingDeviceLayout), the
  // triangles' frames (two float4 each) and weights of the frame, the
  // vertices' weights the steps read, the levels a check computes them in
  // (fold_rings + 1 rows of a float per vertex, kept between checks), and
  // the marks of what changed since (a uchar per triangle, set by the steps;
  // a uchar per vertex for each level and for the commit; fold_guard.cl).
  // The frames depend on the skinned mesh alone: computed once a frame
  // (fold_frames_posed_, reset by begin()).
  cl::Buffer fold_corners_, fold_offsets_, fold_triangles_, fold_frames_,
      triangle_weights_, fold_weights_, fold_dirty_triangles_;
  std::vector<cl::Buffer> fold_levels_, fold_flags_;
  bool fold_frames_posed_ = false;
  // Volume restoration: the layout's volume rows (TrackingDeviceLayout),
  // the chunks' sums, the groups' fractions, missing volumes and secant
  // steps back, and the vertices' weights.
  int volume_group_count_ = 0, volume_triangle_chunks_count_ = 0,
      volume_vertex_chunks_count_ = 0, volume_vertex_entries_count_ = 0;
  cl::Buffer volume_corners_, volume_origins_, volume_rest_, volume_vertices_,
      volume_triangle_chunks_, volume_triangle_chunk_offsets_,
      volume_vertex_chunks_, volume_vertex_chunk_offsets_, volume_groups_,
      volume_areas_, volume_signs_, volume_near_, volume_chunk_sums_[2],
      volume_fractions_, volume_missing_, volume_previous_, volume_back_,
      volume_ones_, volume_zeros_, restore_weights_buffer_;
  // The contact bulge: each vertex's reach (trackingLengths), its band
  // (ping-pong, bulge_band_[bulge_current_] the last), clearance and
  // weight, the chunks' sums of the weights, the groups' volume left to the
  // bulge and fractions, and whether any group needs it (one int).
  cl::Buffer bulge_reaches_, bulge_band_[2], bulge_weights_buffer_,
      bulge_chunk_sums_, bulge_fractions_, bulge_clearances_, bulge_missing_,
      bulge_needed_;
  int bulge_current_ = 0;
  std::vector<std::pair<Stage, cl::Event>> events_;
  TrackingStageTimes times_;
  size_t bytes_ = 0;
};

}  // namespace isk
