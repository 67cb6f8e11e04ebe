// Baked implicit fields evaluated on an OpenCL device.
//
// Host class of kernels/fields/evaluate.cl: uploads a character's baked grids
// (isk/fields/field_grid.hpp) once, then per frame uploads only the fields'
// model -> bone transforms and evaluates every field and their composition
// (isk/fields/field_composition.hpp: blend and bulge pairs through the operator
// tables, uploaded with the fields) at posed points. Results match the CPU
// reference FieldEvaluationJob (isk/fields/field_evaluation.hpp) to float
// rounding on both paths.
//
// Storage of the grids and operator tables (FieldStorage):
//   kImage   one read-only 3D image (CL_RGBA / CL_FLOAT) holding every field
//            as an N^3 tile, and one holding the operator tables stacked in
//            z; the 8 texels around a point are read unfiltered and
//            interpolated in the kernel like the buffer path (hardware
//            filtering weights with 8-bit fractions on GPUs: NVIDIA's gave
//            value errors near 1e-3 and gradients 5% off, enough to stop
//            vertices from marching back to their iso value);
//   kBuffer  float4 buffers, field i at offset i * N^3, table t at t * M^3,
//            interpolated in the kernel exactly as FieldGrid::sampleLocal
//            and OperatorTable::sample;
//   kAuto    the environment variable ISK_FIELD_STORAGE=image|buffer when set
//            (auto or empty: ignored; anything else: isk::Error
//            kInvalidArgument), else kImage on GPU devices and kBuffer on
//            every other device (CPU devices such as PoCL: their image
//            reads run in software and are slower than the buffer path).
// kImage (asked for or picked by kAuto) falls back to kBuffer when the device
// has no image support, no CL_RGBA / CL_FLOAT 3D images, or when the atlas
// would exceed CL_DEVICE_IMAGE3D_MAX_WIDTH / HEIGHT / DEPTH; storage() tells
// what is used and storageReason() why.
// Grids of precision kHalf (isk::roundGridsToHalf; every node must be a
// half, or the constructor names the first that is not) are stored as
// halves: a buffer of 4 halves per node (read with vload_half4), or a
// CL_RGBA / CL_HALF_FLOAT image when the device has them (else CL_FLOAT
// holding the same values); either way the kernels sample exactly the
// values the reference samples, and fieldBytes() says what is held.
//
// Other kernels can sample the same data (kernels/fields/compose.cl: functions
// sample_field, compose_pair, sample_composed): build them with
// buildOptions(), put ISK_FIELD_PARAMS (five consecutive arguments: field
// data, field params, field count, resolution, field cells) and
// ISK_COMPOSITION_PARAMS (six: operator data, pairs, pair count, pair angles,
// controllers, operator scales) among their parameters and bind them with
// setFieldArgs(kernel, first) and setCompositionArgs(kernel, first) after
// setPose(). The evaluate_fields kernel itself takes: 0 points (packed float3),
// 1 point count, 2..5 the field arguments, 6..11 the composition arguments, 12
// composed output (float4 per point), 13 per-field output (float4 per point and
// field, row p * F + i), 14 whether to write the per-field output.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "isk/cl/runtime.hpp"
#include "isk/core/types.hpp"
#include "isk/fields/field_evaluation.hpp"
#include "isk/fields/field_grid.hpp"

namespace isk {

namespace detail {
struct MergedFieldGroups;  // lib/src/cl/field_groups.hpp
}  // namespace detail

// Where the grids and operator tables live on the device (see above).
enum class FieldStorage { kAuto, kImage, kBuffer };

// "auto", "image", "buffer".
const char* fieldStorageName(FieldStorage storage);

// Errors: every call throws isk::Error(kOpenCl) naming the OpenCL call when
// the device fails; calls taking a pose throw kInvalidArgument for one of
// the wrong size or with non-finite transforms, evaluate() for points of
// the wrong shape.
class ClFieldEvaluation {
 public:
  // float4 per field in the params buffer (kernels/fields/sample.cl's layout).
  static constexpr int kParamStride = 7;

  // Validates the grids against `joint_count` (the length of the transform
  // lists evaluate() takes) and the composition (built for these fields by
  // buildComposition; nullptr: the union of all fields) and uploads them;
  // isk::Error kInvalidArgument names the bad field or pair, kOpenCl the
  // failing call.
  //
  // `instances` > 1 (isk::ImplicitCrowd): the fields of that many instances
  // of one character. `fields` and `composition` are one instance's; field
  // k * #fields + i is field i of instance k, posed by joint k *
  // joint_count + its joint, and the pose has joint_count * instances
  // transforms (jointCount()). The grids and the occupied cells are stored
  // once and shared by the instances; fieldCount(), pairCount() and
  // layout() count every instance's.
  ClFieldEvaluation(std::shared_ptr<ClContext> context,
                    const FieldGridSet& fields, int joint_count,
                    FieldStorage storage = FieldStorage::kAuto,
                    const Composition* composition = nullptr,
                    int instances = 1);

  // One character's fields (`fields`, its `composition`, may be null),
  // `instances` times, posed by `joint_count` joints per instance.
  struct FieldGroup {
    const FieldGridSet* fields = nullptr;
    int joint_count = 0;
    const Composition* composition = nullptr;
    int instances = 1;
  };
  // The fields of several characters (a crowd of different characters):
  // group g's instances follow group g - 1's, fields and joints alike; each
  // group's grids are stored once, and each operator table once (groups
  // whose compositions hold the same table, as sharedOperatorTable makes
  // them, share it). The groups
  // share one grid resolution and precision, and one operator table
  // resolution (isk::Error kInvalidArgument naming the character
  // otherwise). One group is the constructor above.
  ClFieldEvaluation(std::shared_ptr<ClContext> context,
                    const std::vector<FieldGroup>& groups,
                    FieldStorage storage = FieldStorage::kAuto);

  // Host path: evaluates at `points` (#P by 3, model space, posed) for the
  // pose `skinning` (#joints skinning transforms). out_composed: #P by 4
  // (value, gradient); out_per_field, when given: (#P * #fields) by 4, row
  // p * #fields + i. Blocking.
  void evaluate(const TransformList& skinning, const Matrix3Xf& points,
                Matrix4Xf& out_composed, Matrix4Xf* out_per_field = nullptr);

  // Device path: evaluates at the first `point_count` packed float3 points
  // (x y z per point) of `points`; results stay on the device in
  // composedBuffer() (and perFieldBuffer() when `per_field`). Returns when
  // the device is done (lastKernelMs() holds this call's kernel time).
  void evaluate(const TransformList& skinning, const cl::Buffer& points,
                int point_count, bool per_field = false);

  // Blocking reads of the last device-path results.
  void readComposed(Matrix4Xf& out);
  void readPerField(Matrix4Xf& out);
  // Last results: point_count float4 (composed), point_count * #fields
  // float4 (per field, valid only after a per_field evaluation). Grown as
  // needed, never shrunk.
  const cl::Buffer& composedBuffer() const { return composed_; }
  const cl::Buffer& perFieldBuffer() const { return per_field_; }

  // Uploads the fields' model -> bone transforms for `skinning` (#joints);
  // evaluate() does it itself. Validates like evaluate().
  void setPose(const TransformList& skinning);

  // Binds field data, field params, field count, resolution and the
  // cells' value bounds (isk::cellValueBounds) to arguments first_index ..
  // first_index + 4 of `kernel` (a kernel of a
  // program built with buildOptions()).
  void setFieldArgs(cl::Kernel& kernel, cl_uint first_index) const;
  // Binds operator data, pairs, pair count, pair angles, controllers and
  // operator scales to arguments first_index .. first_index + 5.
  void setCompositionArgs(cl::Kernel& kernel, cl_uint first_index) const;
  // "-DISK_FIELDS_IMAGE=1", or "-DISK_FIELDS_IMAGE=0" with
  // " -DISK_FIELDS_HALF=1" for half-precision grids in a buffer.
  std::string buildOptions() const;

  // The storage used (kImage or kBuffer) and why, in words.
  FieldStorage storage() const { return storage_; }
  const std::string& storageReason() const { return storage_reason_; }
  // Field data: fieldImage() on the image path, fieldBuffer() on the buffer
  // path (the other is a null object).
  const cl::Image3D& fieldImage() const { return image_; }
  const cl::Buffer& fieldBuffer() const { return nodes_; }
  // kParamStride float4 per field (fields/sample.cl's layout), the last
  // setPose's.
  const cl::Buffer& fieldParams() const { return params_; }
  // The same kParamStride * 4 floats per field, as uploaded.
  const std::vector<float>& hostFieldParams() const { return params_staging_; }

  // The grids without their nodes (joints, frames, boxes), and each
  // field's model -> bone transform at the last setPose.
  const FieldGridSet& layout() const { return layout_; }
  const std::vector<Eigen::Affine3f>& posedToBone() const {
    return posed_to_bone_;
  }
  // Each field's occupiedBox (bone frame; the layout has no nodes).
  const std::vector<Eigen::AlignedBox3f>& occupiedBoxes() const {
    return occupied_boxes_;
  }
  int fieldCount() const { return field_count_; }
  // Grids stored on the device (fieldCount() / instances).
  int gridCount() const { return grid_count_; }
  // Blend and bulge pairs evaluated per point, operator tables uploaded.
  int pairCount() const { return pair_count_; }
  int tableCount() const { return table_count_; }
  int resolution() const { return resolution_; }   // grid nodes per axis
  int jointCount() const { return joint_count_; }  // pose length expected
  // Tiles of the image atlas per axis (1 1 1 on the buffer path).
  const std::array<int, 3>& atlasTiles() const { return tiles_; }
  // Device memory held: field data (the atlas with its unused tiles),
  // params, points and results.
  size_t bytes() const;
  // Device memory of the field data alone, and of the operator tables.
  size_t fieldBytes() const { return field_bytes_; }
  size_t operatorBytes() const { return operator_bytes_; }
  // Kernel time of the last evaluation (profiling event, else host wall
  // time around the finished kernel), and its upload of the pose.
  double lastKernelMs() const { return kernel_ms_; }
  double lastUploadMs() const { return upload_ms_; }

  // The context everything lives in (shared with the caller).
  ClContext& context() { return *context_; }
  const ClContext& context() const { return *context_; }
  std::shared_ptr<ClContext> sharedContext() const { return context_; }

 private:
  void chooseStorage(FieldStorage requested, const FieldGridSet& fields);
  // The program, the grids, tables, cell bounds and static parameters on
  // the device (the constructor's last step).
  void uploadFields(const detail::MergedFieldGroups& merged);
  void uploadImage(const std::vector<const FieldGrid*>& grids);
  void uploadBuffer(const std::vector<const FieldGrid*>& grids);
  void uploadComposition(const Composition* composition);
  void ensureOutputs(int point_count, bool per_field);

  std::shared_ptr<ClContext> context_;
  FieldGridSet layout_;  // the grids without their nodes (joints, frames)
  std::vector<Eigen::AlignedBox3f> occupied_boxes_;  // per field
  int field_count_ = 0;
  int grid_count_ = 0;  // stored grids: one instance's fields
  int resolution_ = 0;
  int joint_count_ = 0;
  FieldStorage storage_ = FieldStorage::kBuffer;
  std::string storage_reason_;
  std::array<int, 3> tiles_ = {1, 1, 1};
  cl::Kernel kernel_;
  cl::Image3D image_;
  cl::Buffer nodes_;
  cl::Buffer params_;
  bool half_ = false;        // buffer of halves (ISK_FIELDS_HALF)
  bool image_half_ = false;  // atlas in CL_HALF_FLOAT
  cl::Buffer cells_;         // cellValueBounds of the grids
  size_t cell_bytes_ = 0;
  cl::Image3D operator_image_;
  cl::Buffer operator_nodes_, pairs_, pair_angles_, controllers_;
  Composition composition_layout_;  // the composition without its tables
  std::vector<float> pair_angles_staging_;  // read by the pose's write
  int pair_count_ = 0, table_count_ = 0, table_resolution_ = 2;
  size_t operator_bytes_ = 0, composition_bytes_ = 0;
  std::vector<float> params_staging_;  // read by non-blocking writes
  std::vector<Eigen::Affine3f> posed_to_bone_;
  cl::Buffer points_, composed_, per_field_, dummy_;
  size_t points_bytes_ = 0, composed_bytes_ = 0, per_field_bytes_ = 0;
  size_t field_bytes_ = 0;
  int last_point_count_ = 0;
  bool last_per_field_ = false;
  double kernel_ms_ = 0, upload_ms_ = 0;
};

}  // namespace isk
