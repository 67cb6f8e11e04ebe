#include "isk/cl/field_evaluation.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

#include "cl/abi_checks.hpp"
#include "cl/device_buffers.hpp"
#include "cl/field_groups.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"

namespace isk {
namespace {

// Each node (i, j, 0)'s unused fourth component: the largest value G of
// the table over the nodes (i', j', k) with i' <= i and j' <= j, every k.
// Trilinear interpolation never exceeds the nodes it weighs, so G at any
// (x, y, theta) whose nodes lie within i, j is at most that (the
// projection's pair bound, project.cl).
void writeOperatorBounds(size_t n, float* table) {
  std::vector<float> column(n * n, 0.f);
  for (size_t k = 0; k < n; ++k)
    for (size_t j = 0; j < n; ++j)
      for (size_t i = 0; i < n; ++i)
        column[i + n * j] =
            std::max(column[i + n * j], table[4 * (i + n * (j + n * k))]);
  for (size_t j = 0; j < n; ++j)
    for (size_t i = 0; i < n; ++i) {
      float m = column[i + n * j];
      if (i > 0) m = std::max(m, table[4 * ((i - 1) + n * j) + 3]);
      if (j > 0) m = std::max(m, table[4 * (i + n * (j - 1)) + 3]);
      table[4 * (i + n * j) + 3] = m;
    }
}

constexpr size_t kFloat4 = 4 * sizeof(float);

using detail::roundUp;
using detail::uploadReadOnly;

using detail::invalid;

// Blocking read of the first `rows` float4 rows of a device buffer.
void readRows(const cl::CommandQueue& queue, const cl::Buffer& buffer,
              size_t rows, const char* call, Matrix4Xf& out) {
  out.resize(static_cast<Eigen::Index>(rows), 4);
  if (out.size() == 0) return;
  try {
    queue.enqueueReadBuffer(buffer, CL_TRUE, 0, out.size() * sizeof(float),
                            out.data());
  } catch (const cl::Error& e) {
    throwClError(e, call);
  }
}

// The half-precision bits of `values` (round to nearest even; exact for
// values rounded by roundGridsToHalf).
std::vector<uint16_t> toHalves(const std::vector<float>& values) {
  std::vector<uint16_t> out(values.size());
  for (size_t i = 0; i < values.size(); ++i)
    out[i] = Eigen::numext::bit_cast<uint16_t>(Eigen::half(values[i]));
  return out;
}

}  // namespace

const char* fieldStorageName(FieldStorage storage) {
  switch (storage) {
    case FieldStorage::kAuto:
      return "auto";
    case FieldStorage::kImage:
      return "image";
    case FieldStorage::kBuffer:
      return "buffer";
  }
  return "unknown";
}

ClFieldEvaluation::ClFieldEvaluation(std::shared_ptr<ClContext> context,
                                     const FieldGridSet& fields,
                                     int joint_count, FieldStorage storage,
                                     const Composition* composition,
                                     int instances)
    : ClFieldEvaluation(
          std::move(context),
          {FieldGroup{&fields, joint_count, composition, instances}}, storage) {
}

ClFieldEvaluation::ClFieldEvaluation(std::shared_ptr<ClContext> context,
                                     const std::vector<FieldGroup>& groups,
                                     FieldStorage storage)
    : context_(std::move(context)) {
  if (!context_) invalid("no context");
  const detail::FieldGroupTotals totals = detail::checkFieldGroups(groups);
  const FieldGridSet* first = groups[0].fields;
  resolution_ = first->resolution;
  grid_count_ = totals.grids;
  field_count_ = totals.fields;
  joint_count_ = totals.joints;
  layout_.resolution = first->resolution;
  layout_.precision = first->precision;
  detail::MergedFieldGroups merged =
      detail::mergeFieldGroups(groups, field_count_);
  layout_.grids = std::move(merged.layout.grids);
  layout_.field_of_joint = std::move(merged.layout.field_of_joint);
  composition_layout_ = std::move(merged.composition_layout);
  pair_count_ = static_cast<int>(composition_layout_.blended_pairs.size());
  table_count_ = static_cast<int>(merged.merged.tables.size());
  table_resolution_ = table_count_ > 0 ? totals.table_resolution : 2;

  chooseStorage(storage, *first);
  half_ = first->precision == GridPrecision::kHalf &&
          storage_ == FieldStorage::kBuffer;
  if (first->precision == GridPrecision::kHalf) {
    if (storage_ == FieldStorage::kBuffer)
      storage_reason_ += "; half-precision grids stored as halves";
    else if (image_half_)
      storage_reason_ += "; half-precision grids in a CL_HALF_FLOAT image";
    else
      storage_reason_ +=
          "; half-precision grids in a CL_FLOAT image (the device has no "
          "CL_RGBA / CL_HALF_FLOAT 3D images: no memory saved)";
  }

  {
    std::vector<Eigen::AlignedBox3f> stored_boxes;
    for (const FieldGrid* g : merged.stored)
      stored_boxes.push_back(occupiedBox(*g));
    for (const int i : merged.grid_of_field)
      occupied_boxes_.push_back(stored_boxes[i]);
  }

  // Static parameters; the rows of the transforms come with each pose.
  params_staging_ = detail::staticFieldParams(
      merged.stored, merged.grid_of_field, resolution_, tiles_.data(),
      storage_ == FieldStorage::kImage);

  uploadFields(merged);
}

void ClFieldEvaluation::uploadFields(const detail::MergedFieldGroups& merged) {
  const std::vector<const FieldGrid*>& stored = merged.stored;
  try {
    cl::Program program = context_->program("fields/evaluate", buildOptions());
    kernel_ = cl::Kernel(program, "evaluate_fields");
    if (storage_ == FieldStorage::kImage)
      uploadImage(stored);
    else
      uploadBuffer(stored);
    uploadComposition(merged.any_composition ? &merged.merged : nullptr);
    // Every grid's cellValueBounds, one after the other.
    std::vector<uint8_t> cells;
    for (const FieldGrid* g : stored) {
      const std::vector<uint8_t> bounds = cellValueBounds(*g);
      cells.insert(cells.end(), bounds.begin(), bounds.end());
    }
    if (cells.empty()) cells.push_back(0);  // a valid buffer
    cells_ = uploadReadOnly(*context_, cells, "ClFieldEvaluation: cell bounds");
    cell_bytes_ = cells.size();
    params_ = uploadReadOnly(*context_, params_staging_,
                             "ClFieldEvaluation: field parameters");
    dummy_ = context_->createBuffer(CL_MEM_READ_WRITE, kFloat4, nullptr,
                                    "ClFieldEvaluation: placeholder");
    composed_ = dummy_;
    per_field_ = dummy_;
  } catch (const cl::Error& e) {
    throwClError(e, std::string("ClFieldEvaluation: uploading ") +
                        std::to_string(field_count_) + " fields (" +
                        fieldStorageName(storage_) + ") to " +
                        context_->info().describe());
  }
}

void ClFieldEvaluation::chooseStorage(FieldStorage requested,
                                      const FieldGridSet& fields) {
  const ClDeviceInfo& info = context_->info();
  FieldStorage wanted = requested;
  if (requested == FieldStorage::kAuto) {
    const char* env = std::getenv("ISK_FIELD_STORAGE");
    const std::string value = env ? env : "";
    if (value == "image") {
      wanted = FieldStorage::kImage;
      storage_reason_ = "ISK_FIELD_STORAGE=image";
    } else if (value == "buffer") {
      wanted = FieldStorage::kBuffer;
      storage_reason_ = "ISK_FIELD_STORAGE=buffer";
    } else if (value.empty() || value == "auto") {
      wanted = info.is_gpu ? FieldStorage::kImage : FieldStorage::kBuffer;
      storage_reason_ =
          info.is_gpu ? "auto: a GPU device" : "auto: not a GPU device";
    } else {
      invalid("ISK_FIELD_STORAGE='" + value +
              "' is not one of image, buffer or auto");
    }
  } else {
    storage_reason_ = std::string("asked for ") + fieldStorageName(requested);
  }
  storage_ = wanted;
  tiles_ = {1, 1, 1};
  if (wanted != FieldStorage::kImage) return;

  std::string problem;
  try {
    const cl::Device& device = context_->device();
    if (!device.getInfo<CL_DEVICE_IMAGE_SUPPORT>()) {
      problem = "the device has no image support";
    } else {
      std::vector<cl::ImageFormat> formats;
      context_->context().getSupportedImageFormats(
          CL_MEM_READ_ONLY, CL_MEM_OBJECT_IMAGE3D, &formats);
      const bool rgba_float =
          std::any_of(formats.begin(), formats.end(), [](const auto& f) {
            return f.image_channel_order == CL_RGBA &&
                   f.image_channel_data_type == CL_FLOAT;
          });
      image_half_ =
          fields.precision == GridPrecision::kHalf &&
          std::any_of(formats.begin(), formats.end(), [](const auto& f) {
            return f.image_channel_order == CL_RGBA &&
                   f.image_channel_data_type == CL_HALF_FLOAT;
          });
      const size_t n = static_cast<size_t>(fields.resolution);
      const size_t max_tiles[3] = {
          device.getInfo<CL_DEVICE_IMAGE3D_MAX_WIDTH>() / n,
          device.getInfo<CL_DEVICE_IMAGE3D_MAX_HEIGHT>() / n,
          device.getInfo<CL_DEVICE_IMAGE3D_MAX_DEPTH>() / n};
      // The atlas as close to a cube as the limits allow, then with the
      // fewest tiles: the filter's texel coordinates stay small (a float
      // coordinate of 2048 keeps only 1/4096 of a texel) and every axis
      // stays far from its limit.
      const size_t count = static_cast<size_t>(std::max(grid_count_, 1));
      size_t tx = 0, ty = 0, tz = 0;
      size_t best_side = 0, best_tiles = 0;
      for (size_t z = 1; z <= std::min(count, max_tiles[2]); ++z) {
        for (size_t y = 1; y <= std::min(count, max_tiles[1]); ++y) {
          const size_t x = (count + y * z - 1) / (y * z);
          if (x > max_tiles[0]) continue;
          const size_t side = std::max({x, y, z});
          const size_t tiles = x * y * z;
          if (tx == 0 || side < best_side ||
              (side == best_side && tiles < best_tiles)) {
            tx = x;
            ty = y;
            tz = z;
            best_side = side;
            best_tiles = tiles;
          }
        }
      }
      const size_t table_depth =
          static_cast<size_t>(std::max(table_count_, 1)) * table_resolution_;
      if (!rgba_float) {
        problem = "the device has no CL_RGBA / CL_FLOAT 3D images";
      } else if (table_depth > device.getInfo<CL_DEVICE_IMAGE3D_MAX_DEPTH>() ||
                 static_cast<size_t>(table_resolution_) >
                     device.getInfo<CL_DEVICE_IMAGE3D_MAX_WIDTH>()) {
        problem = std::to_string(table_count_) + " operator tables of " +
                  std::to_string(table_resolution_) +
                  "^3 exceed CL_DEVICE_IMAGE3D_MAX_*";
      } else if (tx == 0) {
        problem = "an atlas of " + std::to_string(count) + " tiles of " +
                  std::to_string(n) + "^3 exceeds CL_DEVICE_IMAGE3D_MAX_* (" +
                  std::to_string(max_tiles[0] * n) + " x " +
                  std::to_string(max_tiles[1] * n) + " x " +
                  std::to_string(max_tiles[2] * n) + ")";
      } else {
        tiles_ = {static_cast<int>(tx), static_cast<int>(ty),
                  static_cast<int>(tz)};
      }
    }
  } catch (const cl::Error& e) {
    throwClError(
        e, "ClFieldEvaluation: querying image support of " + info.describe());
  }
  if (!problem.empty()) {
    storage_ = FieldStorage::kBuffer;
    tiles_ = {1, 1, 1};
    image_half_ = false;
    storage_reason_ += "; falls back to buffer: " + problem;
  }
}

void ClFieldEvaluation::uploadImage(
    const std::vector<const FieldGrid*>& grids) {
  const size_t n = static_cast<size_t>(resolution_);
  const size_t width = tiles_[0] * n;
  const size_t height = tiles_[1] * n;
  const size_t depth = tiles_[2] * n;
  // Unused tiles stay 0: a tile's last node reads its neighbour with a zero
  // weight, which must not be a NaN.
  std::vector<float> atlas(4 * width * height * depth, 0.f);
  for (int i = 0; i < grid_count_; ++i) {
    const size_t ox = (i % tiles_[0]) * n;
    const size_t oy = ((i / tiles_[0]) % tiles_[1]) * n;
    const size_t oz = (i / (tiles_[0] * tiles_[1])) * n;
    const float* src = grids[i]->nodes.data();
    for (size_t z = 0; z < n; ++z) {
      for (size_t y = 0; y < n; ++y) {
        std::memcpy(&atlas[4 * (ox + width * ((oy + y) + height * (oz + z)))],
                    src + 4 * n * (y + n * z), n * kFloat4);
      }
    }
  }
  if (image_half_) {  // the values are halves already: exact
    const std::vector<uint16_t> halves = toHalves(atlas);
    image_ = cl::Image3D(context_->context(),
                         CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                         cl::ImageFormat(CL_RGBA, CL_HALF_FLOAT), width, height,
                         depth, 0, 0, const_cast<uint16_t*>(halves.data()));
    field_bytes_ = halves.size() * sizeof(uint16_t);
    return;
  }
  image_ =
      cl::Image3D(context_->context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                  cl::ImageFormat(CL_RGBA, CL_FLOAT), width, height, depth, 0,
                  0, atlas.data());
  field_bytes_ = atlas.size() * sizeof(float);
}

void ClFieldEvaluation::uploadBuffer(
    const std::vector<const FieldGrid*>& grids) {
  const size_t per_field =
      4 * static_cast<size_t>(resolution_) * resolution_ * resolution_;
  std::vector<float> nodes(per_field * std::max(grid_count_, 1), 0.f);
  for (int i = 0; i < grid_count_; ++i)
    std::copy(grids[i]->nodes.begin(), grids[i]->nodes.end(),
              nodes.begin() + per_field * i);
  const std::string what = "ClFieldEvaluation: grids of " +
                           std::to_string(grid_count_) + " fields at " +
                           std::to_string(resolution_) + "^3";
  if (half_) {  // the values are halves already: exact
    std::vector<uint16_t> halves = toHalves(nodes);
    nodes_ = context_->createBuffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                                    halves.size() * sizeof(uint16_t),
                                    halves.data(), what + " (half)");
    field_bytes_ = halves.size() * sizeof(uint16_t);
    return;
  }
  nodes_ =
      context_->createBuffer(CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                             nodes.size() * sizeof(float), nodes.data(), what);
  field_bytes_ = nodes.size() * sizeof(float);
}

void ClFieldEvaluation::uploadComposition(const Composition* composition) {
  const cl::Context& ctx = context_->context();
  // Pairs and controllers; one dummy element when there are none (a kernel
  // argument must be a valid buffer).
  std::vector<cl_int> pairs(4 * std::max(pair_count_, 1), 0);
  std::vector<float> controllers(kControllerSamples, 0.f);
  if (composition) {
    controllers.assign(std::max<size_t>(composition->controllers.size(), 1) *
                           kControllerSamples,
                       0.f);
    for (size_t c = 0; c < composition->controllers.size(); ++c)
      std::copy(composition->controllers[c].theta.begin(),
                composition->controllers[c].theta.end(),
                controllers.begin() + c * kControllerSamples);
    for (int k = 0; k < pair_count_; ++k) {
      const FieldPair& p =
          composition_layout_.pairs[composition_layout_.blended_pairs[k]];
      pairs[4 * k + 0] = p.field_a;
      pairs[4 * k + 1] = p.field_b;
      pairs[4 * k + 2] = p.table;
      pairs[4 * k + 3] = p.controller * kControllerSamples;
    }
  }
  pairs_ = uploadReadOnly(*context_, pairs, "ClFieldEvaluation: pairs");
  pair_angles_staging_.assign(std::max(pair_count_, 1), 0.f);
  pair_angles_ = uploadReadOnly(*context_, pair_angles_staging_,
                                "ClFieldEvaluation: pair angles");
  controllers_ =
      uploadReadOnly(*context_, controllers, "ClFieldEvaluation: controllers");
  composition_bytes_ = pairs.size() * sizeof(cl_int) +
                       controllers.size() * sizeof(float) +
                       pair_angles_staging_.size() * sizeof(float);

  // The tables one after the other (z of the image, offset of the buffer);
  // a 2^3 zero table when there are none.
  const size_t n = static_cast<size_t>(table_count_ ? table_resolution_ : 2);
  const size_t per_table = 4 * n * n * n;
  std::vector<float> nodes(per_table * std::max(table_count_, 1), 0.f);
  for (int t = 0; t < table_count_; ++t) {
    std::copy(composition->tables[t]->nodes.begin(),
              composition->tables[t]->nodes.end(),
              nodes.begin() + per_table * t);
    writeOperatorBounds(n, nodes.data() + per_table * t);
  }
  if (storage_ == FieldStorage::kImage)
    operator_image_ =
        cl::Image3D(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                    cl::ImageFormat(CL_RGBA, CL_FLOAT), n, n,
                    n * std::max(table_count_, 1), 0, 0, nodes.data());
  else
    operator_nodes_ =
        uploadReadOnly(*context_, nodes, "ClFieldEvaluation: operator tables");
  operator_bytes_ = nodes.size() * sizeof(float);
}

void ClFieldEvaluation::setCompositionArgs(cl::Kernel& kernel,
                                           cl_uint first_index) const {
  try {
    if (storage_ == FieldStorage::kImage)
      kernel.setArg(first_index, operator_image_);
    else
      kernel.setArg(first_index, operator_nodes_);
    kernel.setArg(first_index + 1, pairs_);
    kernel.setArg(first_index + 2, static_cast<cl_uint>(pair_count_));
    kernel.setArg(first_index + 3, pair_angles_);
    kernel.setArg(first_index + 4, controllers_);
    // As OperatorTable::sample and ThetaController::at compute them.
    const float last = static_cast<float>(table_resolution_ - 1);
    const cl_float4 scales = {{last, last / static_cast<float>(kThetaUnion),
                               static_cast<float>(kControllerSamples - 1) /
                                   static_cast<float>(3.14159265358979323846),
                               0.f}};
    kernel.setArg(first_index + 5, scales);
  } catch (const cl::Error& e) {
    throwClError(e, "ClFieldEvaluation::setCompositionArgs (arguments " +
                        std::to_string(first_index) + " to " +
                        std::to_string(first_index + 5) + ")");
  }
}

std::string ClFieldEvaluation::buildOptions() const {
  if (storage_ == FieldStorage::kImage) return "-DISK_FIELDS_IMAGE=1";
  return half_ ? "-DISK_FIELDS_IMAGE=0 -DISK_FIELDS_HALF=1"
               : "-DISK_FIELDS_IMAGE=0";
}

void ClFieldEvaluation::setFieldArgs(cl::Kernel& kernel,
                                     cl_uint first_index) const {
  try {
    if (storage_ == FieldStorage::kImage)
      kernel.setArg(first_index, image_);
    else
      kernel.setArg(first_index, nodes_);
    kernel.setArg(first_index + 1, params_);
    kernel.setArg(first_index + 2, static_cast<cl_uint>(field_count_));
    kernel.setArg(first_index + 3, static_cast<cl_int>(resolution_));
    kernel.setArg(first_index + 4, cells_);
  } catch (const cl::Error& e) {
    throwClError(e, "ClFieldEvaluation::setFieldArgs (arguments " +
                        std::to_string(first_index) + " to " +
                        std::to_string(first_index + 4) + ")");
  }
}

size_t ClFieldEvaluation::bytes() const {
  return field_bytes_ + cell_bytes_ + operator_bytes_ + composition_bytes_ +
         params_staging_.size() * sizeof(float) + points_bytes_ +
         composed_bytes_ + per_field_bytes_ + kFloat4;
}

void ClFieldEvaluation::setPose(const TransformList& skinning) {
  if (static_cast<int>(skinning.size()) != joint_count_)
    invalid(std::to_string(skinning.size()) +
            " skinning transforms given for a skeleton of " +
            std::to_string(joint_count_) + " joints");
  for (size_t j = 0; j < skinning.size(); ++j)
    if (!skinning[j].matrix().allFinite())
      invalid("skinning transform " + std::to_string(j) + " is not finite");
  // The reference's own transforms, so that both paths sample alike.
  posed_to_bone_ = fieldTransforms(layout_, skinning);
  const std::vector<Eigen::Affine3f>& to_bone = posed_to_bone_;
  const std::vector<Eigen::Vector4f> spheres =
      posedFieldSpheres(layout_, to_bone);
  for (int i = 0; i < field_count_; ++i) {
    float* p = &params_staging_[static_cast<size_t>(i) * kParamStride * 4];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) p[4 * r + c] = to_bone[i].matrix()(r, c);
    for (int c = 0; c < 4; ++c) p[24 + c] = spheres[i][c];
  }
  if (pair_count_ > 0) {
    const std::vector<float> angles =
        pairJointAngles(composition_layout_, layout_, skinning);
    std::copy(angles.begin(), angles.end(), pair_angles_staging_.begin());
  }
  upload_ms_ = 0;
  if (field_count_ == 0) return;
  try {
    cl::Event write;
    const auto start = std::chrono::steady_clock::now();
    // Blocking: the staging vector is rewritten by the next pose.
    context_->queue().enqueueWriteBuffer(
        params_, CL_TRUE, 0,
        static_cast<size_t>(field_count_) * kParamStride * kFloat4,
        params_staging_.data(), nullptr, &write);
    if (pair_count_ > 0)
      context_->queue().enqueueWriteBuffer(pair_angles_, CL_TRUE, 0,
                                           pair_count_ * sizeof(float),
                                           pair_angles_staging_.data());
    upload_ms_ = context_->profilingEnabled() ? eventMilliseconds(write)
                                              : millisecondsSince(start);
  } catch (const cl::Error& e) {
    throwClError(e, "ClFieldEvaluation::setPose");
  }
}

void ClFieldEvaluation::ensureOutputs(int point_count, bool per_field) {
  const size_t composed = static_cast<size_t>(point_count) * kFloat4;
  if (composed > composed_bytes_) {
    composed_ =
        context_->createBuffer(CL_MEM_READ_WRITE, composed, nullptr,
                               "ClFieldEvaluation: composed values of " +
                                   std::to_string(point_count) + " points");
    composed_bytes_ = composed;
  }
  const size_t fields = composed * field_count_;
  if (per_field && fields > per_field_bytes_) {
    per_field_ =
        context_->createBuffer(CL_MEM_READ_WRITE, fields, nullptr,
                               "ClFieldEvaluation: per-field values of " +
                                   std::to_string(point_count) + " points x " +
                                   std::to_string(field_count_) + " fields");
    per_field_bytes_ = fields;
  }
}

void ClFieldEvaluation::evaluate(const TransformList& skinning,
                                 const cl::Buffer& points, int point_count,
                                 bool per_field) {
  if (point_count < 0) invalid("point_count is " + std::to_string(point_count));
  if (point_count > 0 && !points()) invalid("no points buffer");
  setPose(skinning);
  last_point_count_ = 0;
  last_per_field_ = per_field;
  kernel_ms_ = 0;
  if (point_count == 0) return;
  try {
    const size_t needed = 3 * sizeof(float) * static_cast<size_t>(point_count);
    const size_t size = points.getInfo<CL_MEM_SIZE>();
    if (size < needed)
      invalid("the points buffer holds " + std::to_string(size) + " bytes, " +
              std::to_string(point_count) + " packed float3 points need " +
              std::to_string(needed));
    ensureOutputs(point_count, per_field);
    kernel_.setArg(0, points);
    kernel_.setArg(1, static_cast<cl_uint>(point_count));
    setFieldArgs(kernel_, ISK_EVALUATE_ARG_FIELDS);
    setCompositionArgs(kernel_, ISK_EVALUATE_ARG_COMPOSITION);
    kernel_.setArg(ISK_EVALUATE_ARG_OUTPUTS, composed_);
    kernel_.setArg(ISK_EVALUATE_ARG_OUTPUTS + 1,
                   per_field && field_count_ > 0 ? per_field_ : dummy_);
    kernel_.setArg(ISK_EVALUATE_ARG_OUTPUTS + 2,
                   static_cast<cl_uint>(per_field ? 1 : 0));
    cl::Event run;
    const auto start = std::chrono::steady_clock::now();
    context_->queue().enqueueNDRangeKernel(
        kernel_, cl::NullRange,
        cl::NDRange(roundUp(static_cast<size_t>(point_count), 64)),
        cl::NullRange, nullptr, &run);
    run.wait();
    kernel_ms_ = context_->profilingEnabled() ? eventMilliseconds(run)
                                              : millisecondsSince(start);
  } catch (const cl::Error& e) {
    throwClError(e, std::string("ClFieldEvaluation::evaluate (") +
                        fieldStorageName(storage_) + ", " +
                        std::to_string(point_count) + " points) on " +
                        context_->info().describe());
  }
  last_point_count_ = point_count;
}

void ClFieldEvaluation::evaluate(const TransformList& skinning,
                                 const Matrix3Xf& points,
                                 Matrix4Xf& out_composed,
                                 Matrix4Xf* out_per_field) {
  if (points.rows() > static_cast<Eigen::Index>(1 << 30))
    invalid(std::to_string(points.rows()) + " points are too many");
  const int count = static_cast<int>(points.rows());
  const size_t bytes = static_cast<size_t>(points.size()) * sizeof(float);
  try {
    if (bytes > points_bytes_) {
      points_ = context_->createBuffer(
          CL_MEM_READ_ONLY, bytes, nullptr,
          "ClFieldEvaluation: " + std::to_string(count) + " points");
      points_bytes_ = bytes;
    }
    if (bytes > 0)
      context_->queue().enqueueWriteBuffer(points_, CL_TRUE, 0, bytes,
                                           points.data());
  } catch (const cl::Error& e) {
    throwClError(e, "ClFieldEvaluation::evaluate: uploading " +
                        std::to_string(count) + " points");
  }
  evaluate(skinning, points_, count, out_per_field != nullptr);
  readComposed(out_composed);
  if (out_per_field) readPerField(*out_per_field);
}

void ClFieldEvaluation::readComposed(Matrix4Xf& out) {
  readRows(context_->queue(), composed_, last_point_count_,
           "ClFieldEvaluation::readComposed", out);
}

void ClFieldEvaluation::readPerField(Matrix4Xf& out) {
  if (!last_per_field_)
    invalid(
        "readPerField: the last evaluation did not ask for per-field results");
  readRows(context_->queue(), per_field_,
           static_cast<size_t>(last_point_count_) * field_count_,
           "ClFieldEvaluation::readPerField", out);
}

}  // namespace isk
