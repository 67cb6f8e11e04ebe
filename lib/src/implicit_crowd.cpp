#include "isk/implicit_crowd.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "isk/error.hpp"
#include "skinner_fields.hpp"
#include "stopwatch.hpp"

namespace isk {

namespace {

[[noreturn]] void invalid(const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, message);
}

// copies * count as an int; throws naming `what` past int range.
int scaled(int count, int copies, const char* what) {
  const long long total = static_cast<long long>(count) * copies;
  if (total > std::numeric_limits<int>::max())
    invalid(std::string("ImplicitCrowd: ") + std::to_string(copies) +
            " instances of " + std::to_string(count) + " " + what +
            " are more than an int can index");
  return static_cast<int>(total);
}

// values repeated `copies` times.
template <typename T>
std::vector<T> repeated(const std::vector<T>& values, int copies) {
  std::vector<T> out;
  out.reserve(values.size() * static_cast<size_t>(copies));
  for (int i = 0; i < copies; ++i)
    out.insert(out.end(), values.begin(), values.end());
  return out;
}

// Indices repeated `copies` times, copy i's non-negative ones shifted by
// i * shift (negative ones, "none", stay).
template <typename T>
std::vector<T> shifted(const std::vector<T>& indices, int copies,
                       long long shift) {
  std::vector<T> out;
  out.reserve(indices.size() * static_cast<size_t>(copies));
  for (int i = 0; i < copies; ++i)
    for (const T v : indices)
      out.push_back(v >= 0 ? static_cast<T>(v + i * shift) : v);
  return out;
}

Mesh repeatedMesh(const Mesh& mesh, int copies) {
  const int v = mesh.vertexCount();
  const int f = mesh.triangleCount();
  Mesh out;
  out.positions.resize(static_cast<Eigen::Index>(v) * copies, 3);
  out.normals.resize(static_cast<Eigen::Index>(v) * copies, 3);
  out.triangles.resize(static_cast<Eigen::Index>(f) * copies, 3);
  for (int i = 0; i < copies; ++i) {
    out.positions.middleRows(static_cast<Eigen::Index>(i) * v, v) =
        mesh.positions;
    out.normals.middleRows(static_cast<Eigen::Index>(i) * v, v) = mesh.normals;
    out.triangles.middleRows(static_cast<Eigen::Index>(i) * f, f) =
        mesh.triangles.array() + i * v;
    for (MeshPart part : mesh.parts) {
      part.name = "instance " + std::to_string(i) + " " + part.name;
      part.first_vertex += i * v;
      part.first_triangle += i * f;
      out.parts.push_back(part);
    }
  }
  return out;
}

SkinWeights repeatedWeights(const SkinWeights& weights, int copies,
                            int joints) {
  SkinWeights out;
  const uint32_t influences = static_cast<uint32_t>(weights.joints.size());
  out.offsets.push_back(0);
  for (int i = 0; i < copies; ++i)
    for (int v = 0; v < weights.vertexCount(); ++v)
      out.offsets.push_back(weights.offsets[v + 1] + i * influences);
  out.joints.reserve(weights.joints.size() * copies);
  for (int i = 0; i < copies; ++i)
    for (const uint32_t j : weights.joints)
      out.joints.push_back(j + i * joints);
  out.weights = repeated(weights.weights, copies);
  return out;
}

}  // namespace

TrackingMesh replicateTrackingMesh(const TrackingMesh& mesh, int copies,
                                   int joints_per_copy) {
  if (copies < 1)
    invalid("replicateTrackingMesh: " + std::to_string(copies) +
            " copies, expected at least 1");
  const int v = mesh.vertexCount();
  scaled(v, copies, "vertices");
  scaled(mesh.field_count, copies, "fields");
  scaled(static_cast<int>(mesh.rings.neighbours.size()), copies,
         "one-ring entries");
  scaled(static_cast<int>(mesh.normal_adjacency.triangles.size()), copies,
         "adjacency entries");
  const int f = static_cast<int>(mesh.triangles.rows());
  scaled(f, copies, "triangles");
  TrackingMesh out;
  out.rings.representative = shifted(mesh.rings.representative, copies, v);
  out.rings.neighbours = shifted(mesh.rings.neighbours, copies, v);
  out.rings.kinds = repeated(mesh.rings.kinds, copies);
  const uint32_t ring_entries =
      static_cast<uint32_t>(mesh.rings.neighbours.size());
  out.rings.offsets.push_back(0);
  for (int i = 0; i < copies; ++i)
    for (int k = 1; k <= v; ++k)
      out.rings.offsets.push_back(mesh.rings.offsets[k] + i * ring_entries);
  out.relaxation.weights = repeated(mesh.relaxation.weights, copies);
  out.relaxation.rules = repeated(mesh.relaxation.rules, copies);
  out.iso_values = repeated(mesh.iso_values, copies);
  out.home_field = shifted(mesh.home_field, copies, mesh.field_count);
  out.home_margin = repeated(mesh.home_margin, copies);
  for (int i = 0; i < copies; ++i)
    for (TrackingMesh::PartnerPair p : mesh.partner_pairs) {
      p.field_a += i * mesh.field_count;
      p.field_b += i * mesh.field_count;
      p.joint_a += i * joints_per_copy;
      p.joint_b += i * joints_per_copy;
      out.partner_pairs.push_back(p);
    }
  out.field_count = mesh.field_count * copies;
  out.ring_lengths = repeated(mesh.ring_lengths, copies);
  out.triangles.resize(static_cast<Eigen::Index>(f) * copies, 3);
  for (int i = 0; i < copies; ++i)
    out.triangles.middleRows(static_cast<Eigen::Index>(i) * f, f) =
        mesh.triangles.array() + i * v;
  const uint32_t adjacency =
      static_cast<uint32_t>(mesh.normal_adjacency.triangles.size());
  out.normal_adjacency.offsets.push_back(0);
  for (int i = 0; i < copies; ++i)
    for (int k = 1; k <= v; ++k)
      out.normal_adjacency.offsets.push_back(mesh.normal_adjacency.offsets[k] +
                                             i * adjacency);
  out.normal_adjacency.triangles.reserve(static_cast<size_t>(adjacency) *
                                         copies);
  for (int i = 0; i < copies; ++i)
    for (const uint32_t t : mesh.normal_adjacency.triangles)
      out.normal_adjacency.triangles.push_back(t + i * f);
  // The size of one instance: the step and smoothing lengths stay its own.
  out.diagonal = mesh.diagonal;
  // Instance by instance, each in its own march order: by home field (copy
  // i's come after copy i - 1's), then along the Morton curve.
  out.march_order = shifted(mesh.march_order, copies, v);
  return out;
}

struct ImplicitCrowd::State {
  std::shared_ptr<ClContext> context;
  ImplicitSkinnerOptions options;
  std::shared_ptr<const ImplicitFields> fields;
  int instances = 0, vertices = 0, joints = 0;
  std::vector<std::string> joint_names;
  std::unique_ptr<const TrackingMesh> tracking_mesh;
  std::unique_ptr<ClSkinning> skinning;
  std::unique_ptr<ClFieldEvaluation> field_evaluation;
  std::unique_ptr<ClSurfaceTracking> tracking;
  TransformList staging;  // every instance's transforms, one after another
  ImplicitStageTimes times;
  bool has_run = false;
};

ImplicitCrowd::ImplicitCrowd(std::shared_ptr<ClContext> context, const Rig& rig,
                             int instances,
                             const ImplicitSkinnerOptions& options)
    : ImplicitCrowd(
          std::move(context), rig,
          instances >= 1 ? detail::buildSkinnerFields(rig, options) : nullptr,
          instances, options) {}

ImplicitCrowd::ImplicitCrowd(std::shared_ptr<ClContext> context, const Rig& rig,
                             std::shared_ptr<const ImplicitFields> fields,
                             int instances,
                             const ImplicitSkinnerOptions& options)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  if (instances < 1)
    invalid("ImplicitCrowd: " + std::to_string(instances) +
            " instances, expected at least 1");
  if (!context) invalid("ImplicitCrowd: no context");
  if (!fields) invalid("ImplicitCrowd: no fields");
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  rig.validate().throwIfFailed(rig.source);
  if (const Validation v = fieldsFitRig(*fields, rig); !v)
    invalid("ImplicitCrowd: " + v.reason());
  // The neighbourhood lists tag a field index in 16 bits.
  constexpr int kMaxFields = FieldNeighbourhoods::kFieldMask;
  if (static_cast<long long>(fields->grids.fieldCount()) * instances >
      kMaxFields)
    invalid("ImplicitCrowd: " + std::to_string(instances) + " instances of " +
            std::to_string(fields->grids.fieldCount()) +
            " fields are more than the " + std::to_string(kMaxFields) +
            " fields a crowd can hold");
  s.context = std::move(context);
  s.options = options;
  s.fields = std::move(fields);
  s.instances = instances;
  s.vertices = rig.mesh.vertexCount();
  s.joints = rig.skeleton.jointCount();
  scaled(s.vertices, instances, "vertices");
  scaled(s.joints, instances, "joints");
  scaled(static_cast<int>(std::min<size_t>(rig.weights.joints.size(),
                                           std::numeric_limits<int>::max())),
         instances, "skin influences");
  for (const Joint& j : rig.skeleton.joints) s.joint_names.push_back(j.name);
  const TrackingMesh one = TrackingMesh::build(rig.mesh, *s.fields);
  s.tracking_mesh = std::make_unique<const TrackingMesh>(
      replicateTrackingMesh(one, instances, s.joints));
  s.skinning = std::make_unique<ClSkinning>(
      s.context, repeatedMesh(rig.mesh, instances),
      repeatedWeights(rig.weights, instances, s.joints), s.joints * instances);
  // The grids once, shared by the instances.
  s.field_evaluation = std::make_unique<ClFieldEvaluation>(
      s.context, s.fields->grids, s.joints, options.storage,
      &s.fields->composition, instances);
  s.tracking = std::make_unique<ClSurfaceTracking>(
      *s.field_evaluation, *s.tracking_mesh, options.tracking);
}

ImplicitCrowd::~ImplicitCrowd() = default;
ImplicitCrowd::ImplicitCrowd(ImplicitCrowd&&) noexcept = default;
ImplicitCrowd& ImplicitCrowd::operator=(ImplicitCrowd&&) noexcept = default;

ImplicitCrowd::State& ImplicitCrowd::state(const char* what,
                                           bool needs_run) const {
  if (!state_)
    invalid(std::string("ImplicitCrowd::") + what +
            ": the crowd was moved from (it holds no rig)");
  if (needs_run && !state_->has_run)
    invalid(std::string("ImplicitCrowd::") + what +
            " before run(): there is no frame yet");
  return *state_;
}

void ImplicitCrowd::run(const std::vector<TransformList>& skinning) {
  State& s = state("run", false);
  if (static_cast<int>(skinning.size()) != s.instances)
    invalid("ImplicitCrowd::run: " + std::to_string(skinning.size()) +
            " poses given for a crowd of " + std::to_string(s.instances) +
            " instances");
  s.staging.clear();
  s.staging.reserve(static_cast<size_t>(s.joints) * s.instances);
  for (int i = 0; i < s.instances; ++i) {
    const TransformList& pose = skinning[i];
    if (static_cast<int>(pose.size()) != s.joints)
      invalid("ImplicitCrowd::run: instance " + std::to_string(i) + ": " +
              std::to_string(pose.size()) +
              " joint transforms given for a skeleton of " +
              std::to_string(s.joints) + " joints");
    for (int j = 0; j < s.joints; ++j)
      if (!pose[j].matrix().allFinite())
        invalid(
            "ImplicitCrowd::run: instance " + std::to_string(i) +
            ": the transform of joint " + std::to_string(j) +
            (s.joint_names[j].empty() ? "" : " '" + s.joint_names[j] + "'") +
            " is not finite");
    s.staging.insert(s.staging.end(), pose.begin(), pose.end());
  }
  s.times = {};
  s.skinning->enqueue(s.options.base_skinning, s.staging,
                      /*recompute_normals=*/false);
  s.tracking->run(s.staging, s.skinning->positionsBuffer(),
                  s.skinning->normalsBuffer());
  s.skinning->collectTimes();
  s.times.upload_ms =
      s.skinning->lastTimes().upload_ms + s.field_evaluation->lastUploadMs();
  s.times.skinning_ms = s.skinning->lastTimes().skinning_ms;
  s.times.tracking = s.tracking->lastTimes();
  s.has_run = true;
}

void ImplicitCrowd::readPositions(Matrix3Xf& out) {
  State& s = state("readPositions", true);
  const auto start = std::chrono::steady_clock::now();
  s.tracking->readPositions(out);
  s.times.readback_ms += detail::millisecondsSince(start);
}

void ImplicitCrowd::readNormals(Matrix3Xf& out) {
  State& s = state("readNormals", true);
  const auto start = std::chrono::steady_clock::now();
  s.tracking->readNormals(out);
  s.times.readback_ms += detail::millisecondsSince(start);
}

const cl::Buffer& ImplicitCrowd::positionsBuffer() const {
  return state("positionsBuffer", false).tracking->positionsBuffer();
}
const cl::Buffer& ImplicitCrowd::normalsBuffer() const {
  return state("normalsBuffer", false).tracking->normalsBuffer();
}
int ImplicitCrowd::contactCount() {
  return state("contactCount", true).tracking->contactCount();
}
const ImplicitStageTimes& ImplicitCrowd::lastTimes() const {
  return state("lastTimes", false).times;
}
const ImplicitFields& ImplicitCrowd::fields() const {
  return *state("fields", false).fields;
}
const TrackingMesh& ImplicitCrowd::trackingMesh() const {
  return *state("trackingMesh", false).tracking_mesh;
}
ClSurfaceTracking& ImplicitCrowd::tracking() {
  return *state("tracking", false).tracking;
}
ClFieldEvaluation& ImplicitCrowd::fieldEvaluation() {
  return *state("fieldEvaluation", false).field_evaluation;
}
const ImplicitSkinnerOptions& ImplicitCrowd::options() const {
  return state("options", false).options;
}
int ImplicitCrowd::instanceCount() const {
  return state("instanceCount", false).instances;
}
int ImplicitCrowd::vertexCount() const {
  return state("vertexCount", false).vertices;
}
int ImplicitCrowd::jointCount() const {
  return state("jointCount", false).joints;
}

}  // namespace isk
