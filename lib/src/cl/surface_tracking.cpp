#include "isk/cl/surface_tracking.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>

#include "cl/abi_checks.hpp"
#include "cl/device_buffers.hpp"
#include "cl/tracking_layout.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "tracking/tracking_tuning.hpp"
#include "usability.hpp"

namespace isk {
namespace {

// The lane tests' chunks (tracking/project.cl, ISK_LANE_TESTS): ISK_LANE_WIDTH
// lanes (one mask byte per chunk and cell), ISK_LANE_ROWS rows of as many
// floats.
constexpr int kLaneWidth = ISK_LANE_WIDTH;
constexpr size_t kLaneFloats = ISK_LANE_ROWS * kLaneWidth;
static_assert(kLaneWidth == 8, "a lane mask is one byte");

using detail::roundUp;

constexpr const char* kTrackingMesh = "ClSurfaceTracking: the tracking mesh";

template <typename T>
cl::Buffer uploadReadOnly(const ClContext& context, const T* data, size_t count,
                          size_t* bytes) {
  return detail::uploadReadOnly(context, data, count, kTrackingMesh, bytes);
}

template <typename T>
cl::Buffer uploadReadOnly(const ClContext& context, const std::vector<T>& v,
                          size_t* bytes) {
  return detail::uploadReadOnly(context, v, kTrackingMesh, bytes);
}

}  // namespace

ClSurfaceTracking::ClSurfaceTracking(ClFieldEvaluation& fields,
                                     const TrackingMesh& mesh,
                                     const SurfaceTrackingOptions& options)
    : fields_(&fields),
      context_(fields.sharedContext()),
      options_(options),
      mesh_(&mesh),
      vertex_count_(mesh.vertexCount()) {
  options.validate().throwIfFailed("SurfaceTrackingOptions");
  if (mesh.rings.vertexCount() != vertex_count_ ||
      mesh.relaxation.rules.size() != mesh.iso_values.size() ||
      mesh.rest_crease.size() != mesh.iso_values.size())
    throw Error(ErrorCode::kInvalidArgument,
                "ClSurfaceTracking: the tracking mesh is inconsistent (built "
                "by TrackingMesh::build?)");
  cells_per_axis_ = detail::neighbourhoodCellsPerAxis(
      mesh, options, context_->info().is_cpu, kCpuCellsPerAxis);
  const detail::TrackingTuning& tuning = detail::tuningOf(options);
  lane_tests_ = tuning.lane_tests && context_->info().is_cpu &&
                tuning.field_neighbourhoods;
  try {
    buildKernels(fields);
    uploadLayout(detail::trackingDeviceLayout(mesh, options));
    allocateBroadPhase(mesh);
    allocateState(mesh);
  } catch (const cl::Error& e) {
    throwClError(e, "ClSurfaceTracking: uploading the tracking mesh to " +
                        context_->info().describe());
  }
}

void ClSurfaceTracking::buildKernels(const ClFieldEvaluation& fields) {
  // The projection and the contact bulge's probe sample the fields: they
  // are built with their storage options and the broad phase's; the other
  // stages read positions and rings only.
  const std::string sampling_options =
      fields.buildOptions() +
      " -DISK_NEIGHBOUR_CELLS=" + std::to_string(cells_per_axis_) +
      (lane_tests_ ? " -DISK_LANE_TESTS=1" : "");
  cl::Program project = context_->program("tracking/project", sampling_options);
  cl::Program relax = context_->program("tracking/relax");
  cl::Program smooth = context_->program("tracking/smooth");
  cl::Program strain_limit = context_->program("tracking/strain_limit");
  cl::Program finish = context_->program("tracking/finish");
  begin_ = cl::Kernel(project, "track_begin");
  untrack_ = cl::Kernel(project, "track_untrack");
  project_ = cl::Kernel(project, "track_project");
  relax_ = cl::Kernel(relax, "track_relax");
  beta_init_ = cl::Kernel(smooth, "track_beta_init");
  beta_diffuse_ = cl::Kernel(smooth, "track_beta_diffuse");
  smooth_ = cl::Kernel(smooth, "track_smooth");
  limit_strain_ = cl::Kernel(strain_limit, "track_limit_strain");
  strain_offsets_ = cl::Kernel(strain_limit, "track_strain_offsets");
  strain_positions_ = cl::Kernel(strain_limit, "track_strain_positions");
  cl::Program fold_guard = context_->program("tracking/fold_guard");
  fold_frames_kernel_ = cl::Kernel(fold_guard, "track_fold_frames");
  weigh_triangles_ = cl::Kernel(fold_guard, "track_weigh_triangles");
  weigh_folds_ = cl::Kernel(fold_guard, "track_weigh_folds");
  grow_folds_ = cl::Kernel(fold_guard, "track_grow_folds");
  commit_folds_ = cl::Kernel(fold_guard, "track_commit_folds");
  copy_duplicates_ = cl::Kernel(finish, "track_copy_duplicates");
  translate_ = cl::Kernel(finish, "track_translate");
  triangle_normals_kernel_ =
      cl::Kernel(context_->program("normals"), "triangle_normals");
  normals_kernel_ = cl::Kernel(context_->program("normals"), "vertex_normals");
  cl::Program restore = context_->program("tracking/restore_volume");
  volume_chunks_ = cl::Kernel(restore, "track_volume_chunks");
  restore_weights_ = cl::Kernel(restore, "track_restore_weights");
  restore_weighted_ = cl::Kernel(restore, "track_restore_weighted");
  restore_fractions_ = cl::Kernel(restore, "track_restore_fractions");
  restore_apply_ = cl::Kernel(restore, "track_restore_apply");
  restore_correct_ = cl::Kernel(restore, "track_restore_correct");
  bulge_band_init_ = cl::Kernel(restore, "track_bulge_band_init");
  bulge_band_grow_ = cl::Kernel(restore, "track_bulge_band_grow");
  bulge_weights_ = cl::Kernel(restore, "track_bulge_weights");
  bulge_fractions_kernel_ = cl::Kernel(restore, "track_bulge_fractions");
  bulge_clearance_ = cl::Kernel(
      context_->program("tracking/bulge_clearance", sampling_options),
      "track_bulge_clearance");
}

void ClSurfaceTracking::uploadLayout(
    const detail::TrackingDeviceLayout& layout) {
  order_ = layout.order;
  march_count_ = layout.march_count;
  device_index_.assign(order_.size(), -1);
  for (size_t k = 0; k < order_.size(); ++k) device_index_[order_[k]] = k;
  iso_values_ = uploadReadOnly(*context_, layout.iso_values, &bytes_);
  representative_ = uploadReadOnly(*context_, layout.representative, &bytes_);
  finish_source_ = uploadReadOnly(*context_, layout.finish_source, &bytes_);
  begin_source_ = uploadReadOnly(*context_, layout.order, &bytes_);
  rules_ = uploadReadOnly(*context_, layout.rules, &bytes_);
  kinds_ = uploadReadOnly(*context_, layout.kinds, &bytes_);
  home_fields_ = uploadReadOnly(*context_, layout.home_fields, &bytes_);
  home_margins_ = uploadReadOnly(*context_, layout.home_margins, &bytes_);
  home_floors_ = uploadReadOnly(*context_, layout.home_floors, &bytes_);
  rest_creases_ = uploadReadOnly(*context_, layout.rest_creases, &bytes_);
  step_limits_ = uploadReadOnly(*context_, layout.step_limits, &bytes_);
  ring_offsets_ = uploadReadOnly(*context_, layout.ring_offsets, &bytes_);
  ring_neighbours_ = uploadReadOnly(*context_, layout.ring_neighbours, &bytes_);
  ring_weights_ = uploadReadOnly(*context_, layout.ring_weights, &bytes_);
  ring_lengths_ = uploadReadOnly(*context_, layout.ring_lengths, &bytes_);
  near_offsets_ = uploadReadOnly(*context_, layout.near_offsets, &bytes_);
  near_neighbours_ = uploadReadOnly(*context_, layout.near_neighbours, &bytes_);
  near_mean_lengths_ =
      uploadReadOnly(*context_, layout.near_mean_lengths, &bytes_);
  reverse_offsets_ = uploadReadOnly(*context_, layout.reverse_offsets, &bytes_);
  reverse_neighbours_ =
      uploadReadOnly(*context_, layout.reverse_neighbours, &bytes_);
  ring_reverse_offsets_ =
      uploadReadOnly(*context_, layout.ring_reverse_offsets, &bytes_);
  ring_reverse_neighbours_ =
      uploadReadOnly(*context_, layout.ring_reverse_neighbours, &bytes_);
  fold_corners_ = uploadReadOnly(*context_, layout.fold_corners, &bytes_);
  fold_offsets_ = uploadReadOnly(*context_, layout.fold_offsets, &bytes_);
  fold_triangles_ = uploadReadOnly(*context_, layout.fold_triangles, &bytes_);
  volume_group_count_ = static_cast<int>(layout.volume_rest.size());
  volume_triangle_chunks_count_ =
      static_cast<int>(layout.volume_triangle_chunks.size() / 4);
  volume_vertex_chunks_count_ =
      static_cast<int>(layout.volume_vertex_chunks.size() / 4);
  volume_vertex_entries_count_ =
      static_cast<int>(layout.volume_vertices.size());
  volume_corners_ = uploadReadOnly(*context_, layout.volume_corners, &bytes_);
  volume_origins_ = uploadReadOnly(*context_, layout.volume_origins, &bytes_);
  volume_rest_ = uploadReadOnly(*context_, layout.volume_rest, &bytes_);
  volume_vertices_ = uploadReadOnly(*context_, layout.volume_vertices, &bytes_);
  volume_triangle_chunks_ =
      uploadReadOnly(*context_, layout.volume_triangle_chunks, &bytes_);
  volume_triangle_chunk_offsets_ =
      uploadReadOnly(*context_, layout.volume_triangle_chunk_offsets, &bytes_);
  volume_vertex_chunks_ =
      uploadReadOnly(*context_, layout.volume_vertex_chunks, &bytes_);
  volume_vertex_chunk_offsets_ =
      uploadReadOnly(*context_, layout.volume_vertex_chunk_offsets, &bytes_);
  volume_groups_ = uploadReadOnly(*context_, layout.volume_groups, &bytes_);
  volume_areas_ = uploadReadOnly(*context_, layout.volume_areas, &bytes_);
  volume_signs_ = uploadReadOnly(*context_, layout.volume_signs, &bytes_);
  volume_near_ = uploadReadOnly(*context_, layout.volume_near, &bytes_);
  bulge_reaches_ = uploadReadOnly(*context_, layout.bulge_reaches, &bytes_);
}

void ClSurfaceTracking::allocateBroadPhase(const TrackingMesh& mesh) {
  const size_t fields = static_cast<size_t>(mesh.field_count);
  auto int_buffer = [&](size_t count) {
    bytes_ += std::max<size_t>(count, 1) * sizeof(int);
    return context_->createBuffer(
        CL_MEM_READ_ONLY, std::max<size_t>(count, 1) * sizeof(int), nullptr,
        "ClSurfaceTracking: field neighbourhoods of " + std::to_string(fields) +
            " fields");
  };
  partners_ = int_buffer(fields * TrackingMesh::kMaxPartners);
  crease_shifts_ = int_buffer(mesh.rest_crease_pairs.size());
  // Worst cases: every pair in every neighbourhood. The cell lists'
  // entries grow with the poses (begin()).
  const size_t cells = static_cast<size_t>(cells_per_axis_);
  neighbour_offsets_ = int_buffer(fields * cells * cells * cells + 1);
  neighbour_entry_capacity_ = std::max<size_t>(fields * fields, 1);
  neighbour_entries_ = int_buffer(neighbour_entry_capacity_);
  neighbour_pair_offsets_ = int_buffer(fields + 1);
  // The lane tests' chunks come with the first pose (buildLanes); until
  // then, and without lane tests, placeholders for the kernel arguments.
  lane_offsets_ = int_buffer(fields + 1);
  lane_params_ = int_buffer(1);
  lane_masks_ = int_buffer(1);
  neighbour_pairs_ = int_buffer(fields * mesh.partner_pairs.size());
  if (!detail::tuningOf(options_)
           .occupied_cells) {  // no cell clear, no bound: no skipping
    const size_t grid_cells =
        static_cast<size_t>(fields_->layout().resolution) - 1;
    const std::vector<uint8_t> every(std::max<size_t>(fields_->gridCount(), 1) *
                                         grid_cells * grid_cells * grid_cells,
                                     255);
    every_cell_ = uploadReadOnly(*context_, every, &bytes_);
  }
}

void ClSurfaceTracking::allocateState(const TrackingMesh& mesh) {
  const size_t n = static_cast<size_t>(std::max(vertex_count_, 1));
  normal_offsets_ =
      uploadReadOnly(*context_, mesh.normal_adjacency.offsets, &bytes_);
  normal_triangles_ =
      uploadReadOnly(*context_, mesh.normal_adjacency.triangles, &bytes_);
  triangle_count_ = static_cast<int>(mesh.triangles.rows());
  triangles_ =
      uploadReadOnly(*context_, mesh.triangles.data(),
                     3 * static_cast<size_t>(triangle_count_), &bytes_);
  const size_t floats3 = 3 * n * sizeof(float);
  const std::string per_vertex = "ClSurfaceTracking: per-vertex state of " +
                                 std::to_string(n) + " vertices";
  auto rw = [&](size_t bytes) {
    return context_->createBuffer(CL_MEM_READ_WRITE, bytes, nullptr,
                                  per_vertex);
  };
  for (auto& b : positions_) b = rw(floats3);
  normals_ = rw(floats3);
  states_ = rw(n);
  const size_t candidates =
      std::max<size_t>(mesh.dislocation_candidates.size(), 1);
  dislocated_ = context_->createBuffer(
      CL_MEM_READ_ONLY, candidates * sizeof(int), nullptr,
      "ClSurfaceTracking: the dislocation guard's " +
          std::to_string(candidates) + " candidates");
  bytes_ += candidates * sizeof(int);
  prev_gradients_ = rw(n * 4 * sizeof(float));
  relax_frames_ = rw(n * 4 * sizeof(float));
  for (auto& b : beta_) b = rw(2 * n * sizeof(float));
  for (auto& b : strain_offsets_buffers_) b = rw(floats3);
  for (auto& b : strain_active_) {
    b = rw(n);
    context_->queue().enqueueFillBuffer(b, cl_uchar{0}, 0, n);
  }
  fold_levels_.resize(static_cast<size_t>(options_.fold_rings) + 1);
  for (auto& b : fold_levels_) b = rw(n * sizeof(float));
  fold_flags_.resize(static_cast<size_t>(options_.fold_rings) + 2);
  for (auto& b : fold_flags_) {
    b = rw(n);
    context_->queue().enqueueFillBuffer(b, cl_uchar{0}, 0, n);
  }
  bytes_ += fold_levels_.size() * n * sizeof(float) + fold_flags_.size() * n;
  fold_weights_ = rw(n * sizeof(float));
  crease_sources_ = rw(n * sizeof(float));
  restore_weights_buffer_ = rw(n * sizeof(float));
  context_->queue().enqueueFillBuffer(restore_weights_buffer_, 0.0f, 0,
                                      n * sizeof(float));
  for (auto& b : bulge_band_) {
    b = rw(n * sizeof(float));
    context_->queue().enqueueFillBuffer(b, 0.0f, 0, n * sizeof(float));
  }
  bulge_clearances_ = rw(n * sizeof(float));
  context_->queue().enqueueFillBuffer(bulge_clearances_, 1.0f, 0,
                                      n * sizeof(float));
  bulge_weights_buffer_ = rw(n * sizeof(float));
  context_->queue().enqueueFillBuffer(bulge_weights_buffer_, 0.0f, 0,
                                      n * sizeof(float));
  bulge_chunk_sums_ =
      rw(std::max<size_t>(volume_vertex_chunks_count_, 1) * sizeof(float));
  bulge_fractions_ =
      rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  context_->queue().enqueueFillBuffer(
      bulge_fractions_, 0.0f, 0,
      std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  bulge_missing_ = rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  bulge_needed_ = rw(sizeof(cl_int));
  context_->queue().enqueueFillBuffer(bulge_needed_, cl_int{0}, 0,
                                      sizeof(cl_int));
  bytes_ += 3 * n * sizeof(float) +
            (static_cast<size_t>(volume_vertex_chunks_count_) +
             2 * volume_group_count_ + 4) *
                sizeof(float);
  volume_chunk_sums_[0] =
      rw(std::max<size_t>(volume_triangle_chunks_count_, 1) * sizeof(float));
  volume_chunk_sums_[1] =
      rw(std::max<size_t>(volume_vertex_chunks_count_, 1) * sizeof(float));
  volume_fractions_ =
      rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  volume_missing_ =
      rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  volume_previous_ =
      rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  volume_back_ = rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  volume_ones_ = rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  context_->queue().enqueueFillBuffer(
      volume_ones_, 1.0f, 0,
      std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  volume_zeros_ = rw(std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  context_->queue().enqueueFillBuffer(
      volume_zeros_, 0.0f, 0,
      std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  context_->queue().enqueueFillBuffer(
      volume_fractions_, 0.0f, 0,
      std::max<size_t>(volume_group_count_, 1) * sizeof(float));
  bytes_ += n * sizeof(float) + n * sizeof(float) +
            (static_cast<size_t>(volume_triangle_chunks_count_) +
             volume_vertex_chunks_count_ + 4 * volume_group_count_ + 6) *
                sizeof(float);
  // 0 until the first check, and always without the guard (where they
  // still reach the steps, multiplied by 0).
  context_->queue().enqueueFillBuffer(fold_weights_, 0.0f, 0,
                                      n * sizeof(float));
  const size_t triangles = static_cast<size_t>(std::max(triangle_count_, 1));
  fold_frames_ = rw(triangles * 8 * sizeof(float));
  triangle_weights_ = rw(triangles * sizeof(float));
  fold_dirty_triangles_ = rw(triangles);
  context_->queue().enqueueFillBuffer(fold_dirty_triangles_, cl_uchar{0}, 0,
                                      triangles);
  reach_ = rw(n);
  const size_t triangle_floats3 =
      3 * sizeof(float) * static_cast<size_t>(std::max(triangle_count_, 1));
  triangle_normals_ = rw(triangle_floats3);
  bytes_ += 5 * floats3 + 4 * n + sizeof(float) * n +
            (9 * sizeof(float) + 1) *
                static_cast<size_t>(std::max(triangle_count_, 1)) +
            2 * n * 4 * sizeof(float) + 4 * n * sizeof(float) +
            triangle_floats3;
}

void ClSurfaceTracking::addTime(Stage stage, double ms) {
  switch (stage) {
    case kProjection:
      times_.projection_ms += ms;
      break;
    case kRelaxation:
      times_.relaxation_ms += ms;
      break;
    case kSmoothing:
      times_.smoothing_ms += ms;
      break;
    case kVolume:
      times_.volume_ms += ms;
      break;
    case kStrainLimit:
      times_.strain_limit_ms += ms;
      break;
    case kNormals:
      times_.normals_ms += ms;
      break;
  }
}

void ClSurfaceTracking::launch(cl::Kernel& kernel, Stage stage, int items) {
  const cl::NDRange global(
      roundUp(std::max(items < 0 ? vertex_count_ : items, 1), 64));
  cl::Event event;
  if (context_->profilingEnabled()) {
    context_->queue().enqueueNDRangeKernel(kernel, cl::NullRange, global,
                                           cl::NullRange, nullptr, &event);
    events_.emplace_back(stage, event);
    return;
  }
  // Without profiling, each launch is waited for and timed on the host.
  const auto start = std::chrono::steady_clock::now();
  context_->queue().enqueueNDRangeKernel(kernel, cl::NullRange, global,
                                         cl::NullRange, nullptr, &event);
  event.wait();
  addTime(stage, millisecondsSince(start));
}

void ClSurfaceTracking::collectTimes() {
  for (auto& [stage, event] : events_) addTime(stage, eventMilliseconds(event));
  events_.clear();
}

void ClSurfaceTracking::setContactArgs(cl::Kernel& kernel,
                                       cl_uint first_index) const {
  kernel.setArg(first_index, home_fields_);
  kernel.setArg(first_index + 1, home_margins_);
  kernel.setArg(first_index + 2, partners_);
  kernel.setArg(first_index + 3, neighbour_offsets_);
  kernel.setArg(first_index + 4, neighbour_entries_);
  kernel.setArg(first_index + 5, neighbour_pair_offsets_);
  kernel.setArg(first_index + 6, neighbour_pairs_);
  kernel.setArg(first_index + 7, options_.contact_gap);
  const cl_int flags =
      (options_.home_contact ? ISK_CONTACT_HOME_FIELD : 0) |
      (detail::tuningOf(options_).field_neighbourhoods
           ? ISK_CONTACT_NEIGHBOURHOODS
           : 0) |
      (detail::tuningOf(options_).value_bounds ? ISK_CONTACT_VALUE_BOUNDS : 0) |
      (detail::tuningOf(options_).pair_bounds ? ISK_CONTACT_PAIR_BOUNDS : 0);
  kernel.setArg(first_index + 8, flags);
  kernel.setArg(first_index + 9, lane_offsets_);
  kernel.setArg(first_index + 10, lane_params_);
  kernel.setArg(first_index + 11, lane_masks_);
  static_assert(ISK_CONTACT_ARG_COUNT == 12,
                "setContactArgs binds every ISK_TRACKING_PARAMS argument");
}

void ClSurfaceTracking::buildLanes() {
  const FieldNeighbourhoods& nb = neighbourhoods_;
  const int field_count = static_cast<int>(nb.offsets.size()) - 1;
  const int cells = nb.cells_per_axis * nb.cells_per_axis * nb.cells_per_axis;
  const std::vector<float>& params = fields_->hostFieldParams();
  const size_t stride = ClFieldEvaluation::kParamStride * 4;
  lane_offsets_staging_.assign(1, 0);
  for (int h = 0; h < field_count; ++h)
    lane_offsets_staging_.push_back(
        lane_offsets_staging_.back() +
        (nb.offsets[h + 1] - nb.offsets[h] + kLaneWidth - 1) / kLaneWidth);
  const size_t chunks = static_cast<size_t>(lane_offsets_staging_.back());
  lane_params_staging_.assign(std::max<size_t>(chunks, 1) * kLaneFloats, 0.f);
  lane_masks_staging_.assign(std::max<size_t>(chunks, 1) * cells, 0);
  for (int h = 0; h < field_count; ++h) {
    const int first = nb.offsets[h], count = nb.offsets[h + 1] - first;
    const int chunk0 = lane_offsets_staging_[h];
    const int chunks_h = lane_offsets_staging_[h + 1] - chunk0;
    for (int n = 0; n < chunks_h * kLaneWidth; ++n) {
      float* L = &lane_params_staging_[(chunk0 + n / kLaneWidth) * kLaneFloats];
      const int lane = n % kLaneWidth;
      auto put = [&](int row, float value) {
        L[row * kLaneWidth + lane] = value;
      };
      if (n >= count) {
        put(21, -1.f);  // never inside its sphere
        continue;
      }
      const int entry = nb.entries[first + n];
      const int i = entry & FieldNeighbourhoods::kFieldMask;
      const float* p = &params[static_cast<size_t>(i) * stride];
      for (int r = 0; r < 12; ++r) put(r, p[r]);
      for (int a = 0; a < 3; ++a) {
        put(12 + a, p[12 + a]);
        put(15 + a, p[16 + a]);
      }
      for (int a = 0; a < 4; ++a) put(18 + a, p[24 + a]);
      int grid = static_cast<int>(p[15]);
      std::memcpy(&L[22 * kLaneWidth + lane], &entry, sizeof(int));
      std::memcpy(&L[23 * kLaneWidth + lane], &grid, sizeof(int));
    }
    // Each cell's list is a subsequence of the neighbourhood's, in order.
    for (int c = 0; c < cells; ++c) {
      const int cell = h * cells + c;
      uint8_t* masks =
          &lane_masks_staging_[(static_cast<size_t>(chunk0) * cells +
                                static_cast<size_t>(c) * chunks_h)];
      int n = 0;
      for (int e = nb.cell_offsets[cell]; e < nb.cell_offsets[cell + 1]; ++e) {
        while (n < count && nb.entries[first + n] != nb.cell_entries[e]) ++n;
        if (n == count)
          throw Error(ErrorCode::kInternal,
                      "ClSurfaceTracking: a cell list of field " +
                          std::to_string(h) + " is not in its neighbourhood");
        masks[n / kLaneWidth] |= static_cast<uint8_t>(1u << (n % kLaneWidth));
        ++n;
      }
    }
  }
  if (chunks > lane_chunk_capacity_) {  // a pose with longer lists
    bytes_ -= lane_params_.getInfo<CL_MEM_SIZE>() +
              lane_masks_.getInfo<CL_MEM_SIZE>();
    lane_chunk_capacity_ = 2 * chunks;
    bytes_ += lane_chunk_capacity_ * (kLaneFloats * sizeof(float) + cells);
    lane_params_ = context_->createBuffer(
        CL_MEM_READ_ONLY, lane_chunk_capacity_ * kLaneFloats * sizeof(float),
        nullptr, "ClSurfaceTracking: lane tests");
    lane_masks_ =
        context_->createBuffer(CL_MEM_READ_ONLY, lane_chunk_capacity_ * cells,
                               nullptr, "ClSurfaceTracking: lane masks");
  }
  auto& queue = context_->queue();
  queue.enqueueWriteBuffer(lane_offsets_, CL_FALSE, 0,
                           lane_offsets_staging_.size() * sizeof(int),
                           lane_offsets_staging_.data());
  if (chunks > 0) {
    queue.enqueueWriteBuffer(lane_params_, CL_FALSE, 0,
                             chunks * kLaneFloats * sizeof(float),
                             lane_params_staging_.data());
    queue.enqueueWriteBuffer(lane_masks_, CL_FALSE, 0, chunks * cells,
                             lane_masks_staging_.data());
  }
}

void ClSurfaceTracking::begin(const TransformList& skinning,
                              const cl::Buffer& skinned_positions,
                              const cl::Buffer& skinned_normals,
                              const cl::Buffer* start) {
  const size_t needed = 3 * static_cast<size_t>(vertex_count_) * sizeof(float);
  try {
    if (skinned_positions.getInfo<CL_MEM_SIZE>() < needed ||
        skinned_normals.getInfo<CL_MEM_SIZE>() < needed ||
        (start && start->getInfo<CL_MEM_SIZE>() < needed))
      throw Error(ErrorCode::kInvalidArgument,
                  "ClSurfaceTracking::begin: the skinned or start buffers "
                  "hold fewer than " +
                      std::to_string(vertex_count_) + " vertices");
    fields_->setPose(skinning);  // validates the pose
    // Kept in a member: the non-blocking write reads it until it is done.
    partners_staging_ = activePartners(*mesh_, skinning, options_);
    crease_shifts_staging_ = restCreaseShifts(*mesh_, skinning, options_);
    neighbourhoods_ = fieldNeighbourhoods(
        *mesh_, fields_->layout(), fields_->posedToBone(), partners_staging_);
    if (detail::tuningOf(options_).field_neighbourhoods &&
        cells_per_axis_ == 1) {
      neighbourhoods_.cells_per_axis = 1;  // a cell is the whole box
      neighbourhoods_.cell_offsets = neighbourhoods_.offsets;
      neighbourhoods_.cell_entries = neighbourhoods_.entries;
    } else if (detail::tuningOf(options_).field_neighbourhoods) {
      splitNeighbourhoodsIntoCells(neighbourhoods_, fields_->layout(),
                                   fields_->posedToBone(),
                                   fields_->occupiedBoxes(), cells_per_axis_);
      if (neighbourhoods_.cell_entries.size() > neighbour_entry_capacity_) {
        // A pose whose lists are longer than any before: a larger buffer.
        neighbour_entry_capacity_ = 2 * neighbourhoods_.cell_entries.size();
        bytes_ += neighbour_entry_capacity_ * sizeof(int) -
                  neighbour_entries_.getInfo<CL_MEM_SIZE>();
        neighbour_entries_ = context_->createBuffer(
            CL_MEM_READ_ONLY, neighbour_entry_capacity_ * sizeof(int), nullptr,
            "ClSurfaceTracking: field neighbourhoods in cells");
      }
    }
    // Non-blocking writes: the staging vectors are members, kept until the
    // next begin() (after this frame's finish).
    auto write = [&](const cl::Buffer& buffer, const std::vector<int>& v) {
      if (!v.empty())
        context_->queue().enqueueWriteBuffer(buffer, CL_FALSE, 0,
                                             v.size() * sizeof(int), v.data());
    };
    write(partners_, partners_staging_);
    write(crease_shifts_, crease_shifts_staging_);
    write(neighbour_offsets_, neighbourhoods_.cell_offsets);
    write(neighbour_entries_, neighbourhoods_.cell_entries);
    write(neighbour_pair_offsets_, neighbourhoods_.pair_offsets);
    write(neighbour_pairs_, neighbourhoods_.pairs);
    if (lane_tests_) buildLanes();
    times_ = {};
    events_.clear();
    current_ = 0;
    fold_frames_posed_ = false;
    fallback_normals_ = skinned_normals;
    skinned_positions_ = skinned_positions;
    const cl_uint n = static_cast<cl_uint>(vertex_count_);
    begin_.setArg(0, n);
    begin_.setArg(1, skinned_positions);
    begin_.setArg(2, positions_[current_]);
    begin_.setArg(3, iso_values_);
    begin_.setArg(4, representative_);
    begin_.setArg(5, states_);
    begin_.setArg(6, prev_gradients_);
    begin_.setArg(7, relax_frames_);
    begin_.setArg(8, begin_source_);
    begin_.setArg(9, positions_[1 - current_]);
    begin_.setArg(10, reach_);
    begin_.setArg(11, start ? *start : skinned_positions);
    begin_.setArg(12, static_cast<cl_int>(start != nullptr));
    begin_.setArg(13, options_.history_keep);
    beta_current_ = 0;
    user_order_ = false;
    launch(begin_, kProjection);
    if (options_.dislocation_guard) {
      dislocated_staging_.clear();
      for (const int v :
           dislocatedVertices(mesh_->dislocation_candidates, skinning))
        dislocated_staging_.push_back(device_index_[v]);
      if (!dislocated_staging_.empty()) {
        const cl_uint count = static_cast<cl_uint>(dislocated_staging_.size());
        context_->queue().enqueueWriteBuffer(dislocated_, CL_FALSE, 0,
                                             count * sizeof(int),
                                             dislocated_staging_.data());
        untrack_.setArg(0, count);
        untrack_.setArg(1, dislocated_);
        untrack_.setArg(2, states_);
        untrack_.setArg(3, skinned_positions);
        untrack_.setArg(4, begin_source_);
        untrack_.setArg(5, positions_[current_]);
        untrack_.setArg(6, positions_[1 - current_]);
        launch(untrack_, kProjection, static_cast<int>(count));
      }
    }
    begun_ = true;
  } catch (const cl::Error& e) {
    throwClError(e,
                 "ClSurfaceTracking::begin on " + context_->info().describe());
  }
}

void ClSurfaceTracking::checkBegun(const char* stage) const {
  detail::checkBegun("ClSurfaceTracking", stage, begun_);
}

void ClSurfaceTracking::project(int steps) {
  checkBegun("project");
  const float cos_contact = std::cos(options_.contact_angle_degrees *
                                     static_cast<float>(M_PI) / 180.f);
  try {
    project_.setArg(0, static_cast<cl_uint>(march_count_));
    project_.setArg(1, positions_[current_]);
    project_.setArg(2, iso_values_);
    project_.setArg(3, states_);
    project_.setArg(4, prev_gradients_);
    project_.setArg(5, static_cast<cl_int>(steps));
    project_.setArg(6, cl_float4{{options_.sigma, cos_contact,
                                  options_.tolerance, options_.contact_entry}});
    project_.setArg(7, step_limits_);
    setContactArgs(project_, ISK_PROJECT_ARG_CONTACT);
    fields_->setFieldArgs(project_, ISK_PROJECT_ARG_FIELDS);
    if (!detail::tuningOf(options_).occupied_cells)
      project_.setArg(ISK_PROJECT_ARG_FIELDS + ISK_FIELD_ARG_CELLS,
                      every_cell_);
    fields_->setCompositionArgs(project_, ISK_PROJECT_ARG_COMPOSITION);
    project_.setArg(ISK_PROJECT_ARG_RELAX_FRAMES, relax_frames_);
    project_.setArg(ISK_PROJECT_ARG_OTHER_POSITIONS, positions_[1 - current_]);
    project_.setArg(ISK_PROJECT_ARG_HOME_FLOORS, home_floors_);
    project_.setArg(ISK_PROJECT_ARG_REST_CREASES, rest_creases_);
    project_.setArg(ISK_PROJECT_ARG_CREASE_SHIFTS, crease_shifts_);
    launch(project_, kProjection, march_count_);
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSurfaceTracking::project on " + context_->info().describe());
  }
}

void ClSurfaceTracking::relax() {
  checkBegun("relax");
  try {
    relax_.setArg(0, static_cast<cl_uint>(vertex_count_));
    relax_.setArg(1, positions_[current_]);
    relax_.setArg(2, positions_[1 - current_]);
    relax_.setArg(3, states_);
    relax_.setArg(4, relax_frames_);
    relax_.setArg(5, rules_);
    relax_.setArg(6, ring_offsets_);
    relax_.setArg(7, ring_neighbours_);
    relax_.setArg(8, ring_weights_);
    relax_.setArg(9, skinned_positions_);
    relax_.setArg(10, fallback_normals_);
    relax_.setArg(11, begin_source_);
    relax_.setArg(
        12, static_cast<cl_uint>(options_.skinned_ring_relaxation ? 1 : 0));
    relax_.setArg(13, static_cast<cl_uint>(
                          detail::tuningOf(options_).active_vertices ? 1 : 0));
    launch(relax_, kRelaxation);
    current_ = 1 - current_;
  } catch (const cl::Error& e) {
    throwClError(e,
                 "ClSurfaceTracking::relax on " + context_->info().describe());
  }
}

void ClSurfaceTracking::smooth() {
  checkBegun("smooth");
  try {
    const cl_uint n = static_cast<cl_uint>(vertex_count_);
    const cl_uint active = detail::tuningOf(options_).active_vertices ? 1 : 0;
    beta_init_.setArg(0, n);
    beta_init_.setArg(1, states_);
    beta_init_.setArg(2, beta_[0]);
    beta_init_.setArg(3, beta_[1]);
    beta_init_.setArg(4, reverse_offsets_);
    beta_init_.setArg(5, reverse_neighbours_);
    beta_init_.setArg(6, reach_);
    beta_init_.setArg(7, static_cast<cl_uint>(options_.crease_gate ? 1 : 0));
    beta_init_.setArg(8, kinds_);
    beta_init_.setArg(9, ring_offsets_);
    beta_init_.setArg(10, ring_neighbours_);
    beta_init_.setArg(11, near_offsets_);
    beta_init_.setArg(12, near_neighbours_);
    beta_init_.setArg(13, near_mean_lengths_);
    beta_init_.setArg(14, positions_[current_]);
    beta_init_.setArg(15, skinned_positions_);
    beta_init_.setArg(16, begin_source_);
    beta_init_.setArg(17, ring_lengths_);
    beta_init_.setArg(18, crease_sources_);
    launch(beta_init_, kSmoothing);
    int b = 0;
    const int diffusions =
        std::max(options_.beta_diffusion, options_.crease_diffusion);
    auto channels = [&](int k) {  // of diffusion k (0-based)
      return cl_float2{{k < options_.beta_diffusion ? 1.f : 0.f,
                        k < options_.crease_diffusion ? 1.f : 0.f}};
    };
    for (int k = 0; k < diffusions; ++k) {
      beta_diffuse_.setArg(0, n);
      beta_diffuse_.setArg(1, states_);
      beta_diffuse_.setArg(2, near_offsets_);
      beta_diffuse_.setArg(3, near_neighbours_);
      beta_diffuse_.setArg(4, beta_[b]);
      beta_diffuse_.setArg(5, beta_[1 - b]);
      beta_diffuse_.setArg(6, channels(k));
      beta_diffuse_.setArg(7, active);
      beta_diffuse_.setArg(8, static_cast<cl_uint>(k + 1));
      beta_diffuse_.setArg(9, channels(k + 1));
      beta_diffuse_.setArg(10, reverse_offsets_);
      beta_diffuse_.setArg(11, reverse_neighbours_);
      beta_diffuse_.setArg(12, reach_);
      beta_diffuse_.setArg(13, crease_sources_);
      launch(beta_diffuse_, kSmoothing);
      b = 1 - b;
    }
    beta_current_ = b;  // readBeta
    // Beta and gamma are 0 beyond the reach of the last diffusion step.
    const cl_uint smoothed_reach =
        static_cast<cl_uint>(std::max(diffusions, 1));
    const int steps = std::max(options_.smoothing_steps, options_.crease_steps);
    for (int k = 0; k < steps; ++k) {
      smooth_.setArg(0, n);
      smooth_.setArg(1, rules_);
      smooth_.setArg(2, kinds_);
      smooth_.setArg(3, ring_offsets_);
      smooth_.setArg(4, ring_neighbours_);
      smooth_.setArg(5, near_offsets_);
      smooth_.setArg(6, near_neighbours_);
      smooth_.setArg(7, beta_[b]);
      smooth_.setArg(8, positions_[current_]);
      smooth_.setArg(9, positions_[1 - current_]);
      smooth_.setArg(10, cl_float2{{k < options_.smoothing_steps ? 1.f : 0.f,
                                    k < options_.crease_steps ? 1.f : 0.f}});
      smooth_.setArg(11, active ? smoothed_reach : cl_uint{0});
      smooth_.setArg(12, reach_);
      // The rounds leave the vertices still marching different in the two
      // buffers: the first step copies them.
      smooth_.setArg(13, states_);
      smooth_.setArg(14, static_cast<cl_uint>(k == 0 ? 1 : 0));
      launch(smooth_, kSmoothing);
      current_ = 1 - current_;
    }
  } catch (const cl::Error& e) {
    throwClError(e,
                 "ClSurfaceTracking::smooth on " + context_->info().describe());
  }
}

void ClSurfaceTracking::restoreVolume() {
  checkBegun("restoreVolume");
  restoreVolumeWith(/*contact_bulge=*/true);
}

void ClSurfaceTracking::restoreVolumeWith(bool contact_bulge) {
  const bool bulge = contact_bulge && options_.contact_bulge > 0.f &&
                     options_.contact_bulge_steps > 0;
  if (!(options_.volume_restore > 0.f) || volume_group_count_ == 0) {
    // The fractions read back as CpuSurfaceTracking's: 0.
    try {
      context_->queue().enqueueFillBuffer(
          volume_fractions_, 0.0f, 0,
          std::max<size_t>(volume_group_count_, 1) * sizeof(float));
      context_->queue().enqueueFillBuffer(
          bulge_fractions_, 0.0f, 0,
          std::max<size_t>(volume_group_count_, 1) * sizeof(float));
    } catch (const cl::Error& e) {
      throwClError(e, "ClSurfaceTracking::restoreVolume on " +
                          context_->info().describe());
    }
    return;
  }
  try {
    const cl::Buffer& positions = positions_[current_];
    volume_chunks_.setArg(0,
                          static_cast<cl_uint>(volume_triangle_chunks_count_));
    volume_chunks_.setArg(1, volume_triangle_chunks_);
    volume_chunks_.setArg(2, volume_corners_);
    volume_chunks_.setArg(3, volume_origins_);
    volume_chunks_.setArg(4, positions);
    volume_chunks_.setArg(5, volume_chunk_sums_[0]);
    launch(volume_chunks_, kVolume, volume_triangle_chunks_count_);
    // Each vertex's weight, then the chunks' sums in order.
    restore_weights_.setArg(0,
                            static_cast<cl_uint>(volume_vertex_entries_count_));
    restore_weights_.setArg(1, volume_vertices_);
    restore_weights_.setArg(2, states_);
    restore_weights_.setArg(3, beta_[beta_current_]);
    restore_weights_.setArg(4, positions);
    restore_weights_.setArg(5, skinned_positions_);
    restore_weights_.setArg(6, fallback_normals_);
    restore_weights_.setArg(7, begin_source_);
    restore_weights_.setArg(8, volume_signs_);
    restore_weights_.setArg(9, volume_groups_);
    restore_weights_.setArg(10, ring_offsets_);
    restore_weights_.setArg(11, ring_neighbours_);
    restore_weights_.setArg(12, restore_weights_buffer_);
    launch(restore_weights_, kVolume, volume_vertex_entries_count_);
    restore_weighted_.setArg(0,
                             static_cast<cl_uint>(volume_vertex_chunks_count_));
    restore_weighted_.setArg(1, volume_vertex_chunks_);
    restore_weighted_.setArg(2, volume_vertices_);
    restore_weighted_.setArg(3, volume_areas_);
    restore_weighted_.setArg(4, restore_weights_buffer_);
    restore_weighted_.setArg(5, volume_chunk_sums_[1]);
    launch(restore_weighted_, kVolume, volume_vertex_chunks_count_);
    if (bulge)
      context_->queue().enqueueFillBuffer(bulge_needed_, cl_int{0}, 0,
                                          sizeof(cl_int));
    restore_fractions_.setArg(0, static_cast<cl_uint>(volume_group_count_));
    restore_fractions_.setArg(1, volume_triangle_chunk_offsets_);
    restore_fractions_.setArg(2, volume_vertex_chunk_offsets_);
    restore_fractions_.setArg(3, volume_chunk_sums_[0]);
    restore_fractions_.setArg(4, volume_chunk_sums_[1]);
    restore_fractions_.setArg(5, volume_rest_);
    restore_fractions_.setArg(6, options_.volume_restore);
    restore_fractions_.setArg(7, volume_fractions_);
    restore_fractions_.setArg(8, volume_missing_);
    restore_fractions_.setArg(9, static_cast<cl_int>(bulge));
    restore_fractions_.setArg(10, bulge_missing_);
    restore_fractions_.setArg(11, bulge_needed_);
    launch(restore_fractions_, kVolume, volume_group_count_);
    if (bulge) {
      // The band, probe and weights only do work where some group needs the
      // bulge (bulge_needed_): the band is 0 everywhere otherwise.
      const cl_uint n = static_cast<cl_uint>(vertex_count_);
      bulge_band_init_.setArg(0, n);
      bulge_band_init_.setArg(1, states_);
      bulge_band_init_.setArg(2, bulge_needed_);
      bulge_band_init_.setArg(3, bulge_band_[0]);
      launch(bulge_band_init_, kVolume);
      bulge_current_ = 0;
      bulge_band_grow_.setArg(0, n);
      bulge_band_grow_.setArg(1, ring_offsets_);
      bulge_band_grow_.setArg(2, ring_neighbours_);
      bulge_band_grow_.setArg(3, ring_lengths_);
      bulge_band_grow_.setArg(4, bulge_reaches_);
      bulge_band_grow_.setArg(5, bulge_needed_);
      for (int k = 0; k < options_.contact_bulge_steps; ++k) {
        bulge_band_grow_.setArg(6, bulge_band_[bulge_current_]);
        bulge_band_grow_.setArg(7, bulge_band_[1 - bulge_current_]);
        launch(bulge_band_grow_, kVolume);
        bulge_current_ = 1 - bulge_current_;
      }
      // The clearance probe: the largest push times the clearance, in mean
      // ring edge lengths.
      bulge_clearance_.setArg(0, n);
      bulge_clearance_.setArg(1, states_);
      bulge_clearance_.setArg(2, bulge_band_[bulge_current_]);
      bulge_clearance_.setArg(3, positions);
      bulge_clearance_.setArg(4, fallback_normals_);
      bulge_clearance_.setArg(5, begin_source_);
      bulge_clearance_.setArg(6, volume_signs_);
      bulge_clearance_.setArg(7, ring_offsets_);
      bulge_clearance_.setArg(8, ring_lengths_);
      bulge_clearance_.setArg(9, iso_values_);
      bulge_clearance_.setArg(
          10, options_.contact_bulge_clearance * options_.contact_bulge);
      bulge_clearance_.setArg(11, beta_[beta_current_]);
      bulge_clearance_.setArg(12, volume_near_);
      setContactArgs(bulge_clearance_, ISK_BULGE_CLEARANCE_ARG_CONTACT);
      fields_->setFieldArgs(bulge_clearance_, ISK_BULGE_CLEARANCE_ARG_FIELDS);
      if (!detail::tuningOf(options_).occupied_cells)
        bulge_clearance_.setArg(
            ISK_BULGE_CLEARANCE_ARG_FIELDS + ISK_FIELD_ARG_CELLS, every_cell_);
      fields_->setCompositionArgs(bulge_clearance_,
                                  ISK_BULGE_CLEARANCE_ARG_COMPOSITION);
      bulge_clearance_.setArg(ISK_BULGE_CLEARANCE_ARG_OUTPUT,
                              bulge_clearances_);
      launch(bulge_clearance_, kVolume);
      bulge_weights_.setArg(0,
                            static_cast<cl_uint>(volume_vertex_chunks_count_));
      bulge_weights_.setArg(1, volume_vertex_chunks_);
      bulge_weights_.setArg(2, volume_vertices_);
      bulge_weights_.setArg(3, states_);
      bulge_weights_.setArg(4, beta_[beta_current_]);
      bulge_weights_.setArg(5, volume_areas_);
      bulge_weights_.setArg(6, ring_offsets_);
      bulge_weights_.setArg(7, ring_lengths_);
      bulge_weights_.setArg(8, bulge_band_[bulge_current_]);
      bulge_weights_.setArg(9, volume_near_);
      bulge_weights_.setArg(10, bulge_clearances_);
      bulge_weights_.setArg(11, bulge_weights_buffer_);
      bulge_weights_.setArg(12, bulge_chunk_sums_);
      launch(bulge_weights_, kVolume, volume_vertex_chunks_count_);
      bulge_fractions_kernel_.setArg(0,
                                     static_cast<cl_uint>(volume_group_count_));
      bulge_fractions_kernel_.setArg(1, volume_vertex_chunk_offsets_);
      bulge_fractions_kernel_.setArg(2, bulge_chunk_sums_);
      bulge_fractions_kernel_.setArg(3, bulge_missing_);
      bulge_fractions_kernel_.setArg(4, options_.contact_bulge);
      bulge_fractions_kernel_.setArg(5, bulge_fractions_);
      launch(bulge_fractions_kernel_, kVolume, volume_group_count_);
    } else if (contact_bulge) {
      context_->queue().enqueueFillBuffer(
          bulge_fractions_, 0.0f, 0,
          std::max<size_t>(volume_group_count_, 1) * sizeof(float));
    }
    // Without the bulge asked for, its band, weights and fractions stay
    // those of the last restoration with it (CpuSurfaceTracking's too).
    const cl::Buffer& bulge_fractions =
        bulge ? bulge_fractions_ : volume_zeros_;
    restore_apply_.setArg(0, static_cast<cl_uint>(vertex_count_));
    restore_apply_.setArg(1, volume_groups_);
    restore_apply_.setArg(2, restore_weights_buffer_);
    restore_apply_.setArg(3, volume_fractions_);
    restore_apply_.setArg(4, volume_ones_);
    restore_apply_.setArg(5, volume_near_);
    restore_apply_.setArg(6, options_.volume_restore);
    restore_apply_.setArg(7, fallback_normals_);
    restore_apply_.setArg(8, begin_source_);
    restore_apply_.setArg(9, volume_signs_);
    restore_apply_.setArg(10, positions);
    restore_apply_.setArg(11, static_cast<cl_int>(bulge));
    restore_apply_.setArg(12, bulge_weights_buffer_);
    restore_apply_.setArg(13, bulge_fractions);
    restore_apply_.setArg(14, options_.contact_bulge);
    launch(restore_apply_, kVolume);
    // The secant step back where a group went past its rest volume.
    launch(volume_chunks_, kVolume, volume_triangle_chunks_count_);
    restore_correct_.setArg(0, static_cast<cl_uint>(volume_group_count_));
    restore_correct_.setArg(1, volume_triangle_chunk_offsets_);
    restore_correct_.setArg(2, volume_chunk_sums_[0]);
    restore_correct_.setArg(3, volume_rest_);
    restore_correct_.setArg(4, volume_missing_);
    restore_correct_.setArg(5, volume_fractions_);
    restore_correct_.setArg(6, volume_previous_);
    restore_correct_.setArg(7, volume_back_);
    restore_correct_.setArg(8, bulge_fractions);
    launch(restore_correct_, kVolume, volume_group_count_);
    restore_apply_.setArg(3, volume_previous_);
    restore_apply_.setArg(4, volume_back_);
    launch(restore_apply_, kVolume);
  } catch (const cl::Error& e) {
    throwClError(e, "ClSurfaceTracking::restoreVolume on " +
                        context_->info().describe());
  }
}

void ClSurfaceTracking::readVolumeFractions(std::vector<float>& out) {
  checkBegun("readVolumeFractions");
  out.resize(volume_group_count_);
  if (volume_group_count_ > 0)
    readFloats(volume_fractions_, out.data(), out.size() * sizeof(float),
               "readVolumeFractions");
}

void ClSurfaceTracking::readRestoreWeights(std::vector<float>& out) {
  checkBegun("readRestoreWeights");
  readByVertex(restore_weights_buffer_, out, "readRestoreWeights");
}

void ClSurfaceTracking::readBulgeFractions(std::vector<float>& out) {
  checkBegun("readBulgeFractions");
  out.resize(volume_group_count_);
  if (volume_group_count_ > 0)
    readFloats(bulge_fractions_, out.data(), out.size() * sizeof(float),
               "readBulgeFractions");
}

void ClSurfaceTracking::readBulgeBand(std::vector<float>& out) {
  checkBegun("readBulgeBand");
  readByVertex(bulge_band_[bulge_current_], out, "readBulgeBand");
}

void ClSurfaceTracking::readBulgeWeights(std::vector<float>& out) {
  checkBegun("readBulgeWeights");
  readByVertex(bulge_weights_buffer_, out, "readBulgeWeights");
}

void ClSurfaceTracking::readFoldWeights(std::vector<float>& out) {
  checkBegun("readFoldWeights");
  readByVertex(fold_weights_, out, "readFoldWeights");
}

void ClSurfaceTracking::readByVertex(const cl::Buffer& buffer,
                                     std::vector<float>& out,
                                     const char* what) {
  std::vector<float> by_device(vertex_count_);
  if (vertex_count_ > 0)
    readFloats(buffer, by_device.data(), by_device.size() * sizeof(float),
               what);
  out.assign(vertex_count_, 0.f);
  for (int k = 0; k < vertex_count_; ++k) out[order_[k]] = by_device[k];
}

void ClSurfaceTracking::limitStrain() {
  checkBegun("limitStrain");
  limitStrainSteps(options_.strain_limit_steps);
}

void ClSurfaceTracking::restoreVolumeAgain() {
  checkBegun("restoreVolumeAgain");
  if (!restoresVolumeAgain(options_)) return;
  // The inward moves only: the contact bulge would push the band beside the
  // contacts out again, which the short limit after it does not even out.
  restoreVolumeWith(/*contact_bulge=*/false);
  limitStrainSteps(options_.restore_again_steps);
}

void ClSurfaceTracking::limitStrainSteps(int steps) {
  if (steps <= 0) return;
  try {
    const cl_uint n = static_cast<cl_uint>(vertex_count_);
    strain_offsets_.setArg(0, n);
    strain_offsets_.setArg(1, positions_[current_]);
    strain_offsets_.setArg(2, skinned_positions_);
    strain_offsets_.setArg(3, begin_source_);
    strain_offsets_.setArg(4, strain_offsets_buffers_[0]);
    strain_offsets_.setArg(5, strain_offsets_buffers_[1]);
    launch(strain_offsets_, kStrainLimit);
    const cl_uint triangles = static_cast<cl_uint>(triangle_count_);
    if (options_.fold_guard && triangle_count_ > 0 && !fold_frames_posed_) {
      fold_frames_kernel_.setArg(0, triangles);
      fold_frames_kernel_.setArg(1, skinned_positions_);
      fold_frames_kernel_.setArg(2, fallback_normals_);
      fold_frames_kernel_.setArg(3, begin_source_);
      fold_frames_kernel_.setArg(4, fold_corners_);
      fold_frames_kernel_.setArg(5, fold_frames_);
      launch(fold_frames_kernel_, kStrainLimit, triangle_count_);
      fold_frames_posed_ = true;
    }
    // Step k reads offsets b and active marks b, and writes the others.
    int b = 0;
    for (int k = 0; k < steps; ++k) {
      if (options_.fold_guard && triangle_count_ > 0 &&
          k % options_.fold_check_steps == 0)
        checkFolds(strain_offsets_buffers_[b], k == 0, strain_active_[b]);
      limit_strain_.setArg(0, static_cast<cl_uint>(march_count_));
      limit_strain_.setArg(1, static_cast<cl_int>(k == 0));
      limit_strain_.setArg(2, strain_active_[b]);
      limit_strain_.setArg(3, strain_active_[1 - b]);
      limit_strain_.setArg(4, strain_offsets_buffers_[b]);
      limit_strain_.setArg(5, strain_offsets_buffers_[1 - b]);
      limit_strain_.setArg(6, ring_offsets_);
      limit_strain_.setArg(7, ring_neighbours_);
      limit_strain_.setArg(8, ring_lengths_);
      limit_strain_.setArg(9, options_.strain_limit);
      // Without the guard both limits are strain_limit: the weights are moot.
      limit_strain_.setArg(10, fold_weights_);
      limit_strain_.setArg(11, options_.fold_guard ? options_.fold_strain_limit
                                                   : options_.strain_limit);
      limit_strain_.setArg(12, ring_reverse_offsets_);
      limit_strain_.setArg(13, ring_reverse_neighbours_);
      limit_strain_.setArg(14, fold_offsets_);
      limit_strain_.setArg(15, fold_triangles_);
      limit_strain_.setArg(16, fold_dirty_triangles_);
      launch(limit_strain_, kStrainLimit, march_count_);
      b = 1 - b;
    }
    strain_positions_.setArg(0, n);
    strain_positions_.setArg(1, positions_[current_]);
    strain_positions_.setArg(2, skinned_positions_);
    strain_positions_.setArg(3, begin_source_);
    strain_positions_.setArg(4, strain_offsets_buffers_[b]);
    launch(strain_positions_, kStrainLimit);
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSurfaceTracking::limitStrain on " + context_->info().describe());
  }
}

void ClSurfaceTracking::checkFolds(const cl::Buffer& offsets, bool all,
                                   const cl::Buffer& active) {
  // The weights from these offsets: per triangle, per vertex (level 0),
  // fold_rings rings out (one level each), then committed.
  const cl_uint n = static_cast<cl_uint>(vertex_count_);
  const cl_int every = all ? 1 : 0;
  const int rings = options_.fold_rings;
  weigh_triangles_.setArg(0, static_cast<cl_uint>(triangle_count_));
  weigh_triangles_.setArg(1, offsets);
  weigh_triangles_.setArg(2, skinned_positions_);
  weigh_triangles_.setArg(3, begin_source_);
  weigh_triangles_.setArg(4, fold_corners_);
  weigh_triangles_.setArg(5, fold_frames_);
  weigh_triangles_.setArg(6, triangle_weights_);
  weigh_triangles_.setArg(7, tiltGuardCosine(options_));
  weigh_triangles_.setArg(8, tiltGuardScale(options_));
  weigh_triangles_.setArg(9, fold_dirty_triangles_);
  weigh_triangles_.setArg(10, every);
  weigh_triangles_.setArg(11, fold_flags_[0]);
  launch(weigh_triangles_, kStrainLimit, triangle_count_);
  weigh_folds_.setArg(0, n);
  weigh_folds_.setArg(1, fold_offsets_);
  weigh_folds_.setArg(2, fold_triangles_);
  weigh_folds_.setArg(3, triangle_weights_);
  weigh_folds_.setArg(4, fold_levels_[0]);
  weigh_folds_.setArg(5, fold_flags_[0]);
  weigh_folds_.setArg(6, fold_flags_[1]);
  weigh_folds_.setArg(7, static_cast<cl_int>(rings > 0));
  weigh_folds_.setArg(8, ring_reverse_offsets_);
  weigh_folds_.setArg(9, ring_reverse_neighbours_);
  weigh_folds_.setArg(10, every);
  launch(weigh_folds_, kStrainLimit);
  for (int r = 1; r <= rings; ++r) {
    grow_folds_.setArg(0, n);
    grow_folds_.setArg(1, fold_levels_[r - 1]);
    grow_folds_.setArg(2, fold_levels_[r]);
    grow_folds_.setArg(3, fold_flags_[r]);
    grow_folds_.setArg(4, fold_flags_[r + 1]);
    grow_folds_.setArg(5, static_cast<cl_int>(r < rings));
    grow_folds_.setArg(6, ring_offsets_);
    grow_folds_.setArg(7, ring_neighbours_);
    grow_folds_.setArg(8, ring_reverse_offsets_);
    grow_folds_.setArg(9, ring_reverse_neighbours_);
    grow_folds_.setArg(10, every);
    launch(grow_folds_, kStrainLimit);
  }
  commit_folds_.setArg(0, n);
  commit_folds_.setArg(1, static_cast<cl_uint>(march_count_));
  commit_folds_.setArg(2, fold_levels_[rings]);
  commit_folds_.setArg(3, fold_weights_);
  commit_folds_.setArg(4, fold_flags_[rings + 1]);
  commit_folds_.setArg(5, active);
  commit_folds_.setArg(6, ring_reverse_offsets_);
  commit_folds_.setArg(7, ring_reverse_neighbours_);
  commit_folds_.setArg(8, every);
  launch(commit_folds_, kStrainLimit);
}

void ClSurfaceTracking::finish() {
  checkBegun("finish");
  try {
    const cl_uint n = static_cast<cl_uint>(vertex_count_);
    // Back to the mesh's order, seam copies from their representative.
    copy_duplicates_.setArg(0, n);
    copy_duplicates_.setArg(1, finish_source_);
    copy_duplicates_.setArg(2, positions_[current_]);
    copy_duplicates_.setArg(3, positions_[1 - current_]);
    launch(copy_duplicates_, kNormals);
    current_ = 1 - current_;
    user_order_ = true;
    triangle_normals_kernel_.setArg(0, static_cast<cl_uint>(triangle_count_));
    triangle_normals_kernel_.setArg(1, positions_[current_]);
    triangle_normals_kernel_.setArg(2, triangles_);
    triangle_normals_kernel_.setArg(3, triangle_normals_);
    launch(triangle_normals_kernel_, kNormals, triangle_count_);
    normals_kernel_.setArg(0, n);
    normals_kernel_.setArg(1, triangle_normals_);
    normals_kernel_.setArg(2, normal_offsets_);
    normals_kernel_.setArg(3, normal_triangles_);
    normals_kernel_.setArg(4, fallback_normals_);
    normals_kernel_.setArg(5, normals_);
    launch(normals_kernel_, kNormals);
  } catch (const cl::Error& e) {
    throwClError(e,
                 "ClSurfaceTracking::finish on " + context_->info().describe());
  }
}

void ClSurfaceTracking::translate(const Eigen::Vector3f& offset) {
  checkBegun("translate");
  try {
    translate_.setArg(0, static_cast<cl_uint>(vertex_count_));
    translate_.setArg(1, positions_[current_]);
    translate_.setArg(2, offset.x());
    translate_.setArg(3, offset.y());
    translate_.setArg(4, offset.z());
    launch(translate_, kNormals);
    context_->queue().finish();
    collectTimes();
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClSurfaceTracking::translate on " + context_->info().describe());
  }
}

void ClSurfaceTracking::run(const TransformList& skinning,
                            const cl::Buffer& skinned_positions,
                            const cl::Buffer& skinned_normals,
                            const cl::Buffer* start) {
  begin(skinning, skinned_positions, skinned_normals, start);
  for (int r = 0; r < options_.rounds; ++r) {
    project(options_.projection_steps);
    if (options_.relaxation) relax();
  }
  smooth();
  restoreVolume();
  limitStrain();
  restoreVolumeAgain();
  finish();
  try {
    context_->queue().finish();
  } catch (const cl::Error& e) {
    throwClError(e, "ClSurfaceTracking::run on " + context_->info().describe());
  }
  collectTimes();
}

void ClSurfaceTracking::setState(const Matrix3Xf& positions,
                                 const std::vector<TrackState>& states,
                                 const Matrix4Xf& prev_gradients,
                                 const Matrix4Xf* relax_frames) {
  checkBegun("setState");
  if (positions.rows() != vertex_count_ ||
      static_cast<int>(states.size()) != vertex_count_ ||
      prev_gradients.rows() != vertex_count_ ||
      (relax_frames && relax_frames->rows() != vertex_count_))
    throw Error(ErrorCode::kInvalidArgument,
                "ClSurfaceTracking::setState: expected " +
                    std::to_string(vertex_count_) + " rows");
  try {
    const cl::CommandQueue& queue = context_->queue();
    const Matrix3Xf device_positions = toDevice(positions);
    for (const cl::Buffer& buffer : positions_)  // both: see track_relax
      queue.enqueueWriteBuffer(buffer, CL_TRUE, 0,
                               device_positions.size() * sizeof(float),
                               device_positions.data());
    std::vector<TrackState> device_states(states.size());
    for (size_t k = 0; k < states.size(); ++k)
      device_states[k] = states[order_[k]];
    queue.enqueueWriteBuffer(states_, CL_TRUE, 0, device_states.size(),
                             device_states.data());
    const Matrix4Xf device_prev = toDevice(prev_gradients);
    queue.enqueueWriteBuffer(prev_gradients_, CL_TRUE, 0,
                             device_prev.size() * sizeof(float),
                             device_prev.data());
    if (relax_frames) {
      const Matrix4Xf device_frames = toDevice(*relax_frames);
      queue.enqueueWriteBuffer(relax_frames_, CL_TRUE, 0,
                               device_frames.size() * sizeof(float),
                               device_frames.data());
    }
    user_order_ = false;
  } catch (const cl::Error& e) {
    throwClError(e, "ClSurfaceTracking::setState");
  }
}

void ClSurfaceTracking::readFloats(const cl::Buffer& buffer, void* out,
                                   size_t bytes, const char* what) {
  checkBegun(what);
  try {
    context_->queue().enqueueReadBuffer(buffer, CL_TRUE, 0, bytes, out);
  } catch (const cl::Error& e) {
    throwClError(e, std::string("ClSurfaceTracking::") + what);
  }
}

void ClSurfaceTracking::readPositions(Matrix3Xf& out) {
  out.resize(vertex_count_, 3);
  readFloats(positions_[current_], out.data(), out.size() * sizeof(float),
             "readPositions");
  if (!user_order_) out = fromDevice(out);
}

void ClSurfaceTracking::readNormals(Matrix3Xf& out) {
  out.resize(vertex_count_, 3);
  readFloats(normals_, out.data(), out.size() * sizeof(float), "readNormals");
}

void ClSurfaceTracking::readStates(std::vector<TrackState>& out) {
  std::vector<TrackState> device(vertex_count_);
  readFloats(states_, device.data(), device.size(), "readStates");
  out.resize(vertex_count_);
  for (int k = 0; k < vertex_count_; ++k) out[order_[k]] = device[k];
}

void ClSurfaceTracking::readBeta(std::vector<float>& out) {
  std::vector<float> device(2 * static_cast<size_t>(vertex_count_));
  readFloats(beta_[beta_current_], device.data(), device.size() * sizeof(float),
             "readBeta");
  out.resize(device.size());
  for (int k = 0; k < vertex_count_; ++k) {
    out[2 * static_cast<size_t>(order_[k])] = device[2 * k];
    out[2 * static_cast<size_t>(order_[k]) + 1] = device[2 * k + 1];
  }
}

void ClSurfaceTracking::readPreviousGradients(Matrix4Xf& out) {
  out.resize(vertex_count_, 4);
  readFloats(prev_gradients_, out.data(), out.size() * sizeof(float),
             "readPreviousGradients");
  out = fromDevice(out);
}

void ClSurfaceTracking::readRelaxFrames(Matrix4Xf& out) {
  out.resize(vertex_count_, 4);
  readFloats(relax_frames_, out.data(), out.size() * sizeof(float),
             "readRelaxFrames");
  out = fromDevice(out);
}

int ClSurfaceTracking::contactCount() {
  std::vector<TrackState> states;
  readStates(states);
  return countStates(states).contact;
}

}  // namespace isk
