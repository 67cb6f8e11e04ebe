#include "isk/implicit_crowd.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "frame_pipeline.hpp"
#include "isk/core/error.hpp"
#include "isk/core/stopwatch.hpp"
#include "skinner_fields.hpp"
#include "usability.hpp"

namespace isk {

namespace {

[[noreturn]] void invalid(const std::string& message) {
  throw Error(ErrorCode::kInvalidArgument, message);
}

// One character's rows of a crowd: its mesh and weights, `copies` times,
// each copy's joints `joints` after the last's.
struct Copies {
  const Mesh* mesh;
  const SkinWeights* weights;
  int copies;
  int joints;
};

// The meshes one after the other (triangles shifted; parts named by
// instance).
Mesh concatenatedMesh(const std::vector<Copies>& parts) {
  Eigen::Index vertices = 0, triangles = 0;
  for (const Copies& c : parts) {
    vertices += static_cast<Eigen::Index>(c.mesh->vertexCount()) * c.copies;
    triangles += static_cast<Eigen::Index>(c.mesh->triangleCount()) * c.copies;
  }
  Mesh out;
  out.positions.resize(vertices, 3);
  out.normals.resize(vertices, 3);
  out.triangles.resize(triangles, 3);
  Eigen::Index v0 = 0, f0 = 0;
  int instance = 0;
  for (const Copies& c : parts) {
    const Mesh& mesh = *c.mesh;
    const int v = mesh.vertexCount();
    const int f = mesh.triangleCount();
    for (int i = 0; i < c.copies; ++i, ++instance) {
      out.positions.middleRows(v0, v) = mesh.positions;
      out.normals.middleRows(v0, v) = mesh.normals;
      out.triangles.middleRows(f0, f) =
          mesh.triangles.array() + static_cast<int>(v0);
      for (MeshPart part : mesh.parts) {
        part.name = "instance " + std::to_string(instance) + " " + part.name;
        part.first_vertex += static_cast<int>(v0);
        part.first_triangle += static_cast<int>(f0);
        out.parts.push_back(part);
      }
      v0 += v;
      f0 += f;
    }
  }
  return out;
}

// The weights one after the other, each copy's joints shifted past the
// joints of the copies before it.
SkinWeights concatenatedWeights(const std::vector<Copies>& parts) {
  SkinWeights out;
  out.offsets.push_back(0);
  uint32_t joint_offset = 0;
  for (const Copies& c : parts) {
    const SkinWeights& weights = *c.weights;
    for (int i = 0; i < c.copies; ++i) {
      const uint32_t influence_offset = out.offsets.back();
      for (int v = 0; v < weights.vertexCount(); ++v)
        out.offsets.push_back(weights.offsets[v + 1] + influence_offset);
      for (const uint32_t j : weights.joints)
        out.joints.push_back(j + joint_offset);
      out.weights.insert(out.weights.end(), weights.weights.begin(),
                         weights.weights.end());
      joint_offset += static_cast<uint32_t>(c.joints);
    }
  }
  return out;
}

}  // namespace

TrackingMesh concatenateTrackingMeshes(
    const std::vector<TrackingMeshCopies>& parts) {
  if (parts.empty()) invalid("concatenateTrackingMeshes: no parts");
  long long vertices = 0, fields = 0, ring_entries = 0, adjacency = 0,
            triangles = 0;
  bool one_diagonal = true;
  for (size_t p = 0; p < parts.size(); ++p) {
    const TrackingMeshCopies& c = parts[p];
    const std::string where =
        "concatenateTrackingMeshes: part " + std::to_string(p) + ": ";
    if (!c.mesh) invalid(where + "no tracking mesh");
    if (c.copies < 1)
      invalid(where + std::to_string(c.copies) +
              " copies, expected at least 1");
    if (c.joints_per_copy < 0)
      invalid(where + std::to_string(c.joints_per_copy) + " joints per copy");
    const TrackingMesh& m = *c.mesh;
    if (!m.vertex_diagonals.empty() &&
        static_cast<int>(m.vertex_diagonals.size()) != m.vertexCount())
      invalid(where + std::to_string(m.vertex_diagonals.size()) +
              " vertex diagonals for " + std::to_string(m.vertexCount()) +
              " vertices");
    vertices += static_cast<long long>(m.vertexCount()) * c.copies;
    fields += static_cast<long long>(m.field_count) * c.copies;
    ring_entries +=
        static_cast<long long>(m.rings.neighbours.size()) * c.copies;
    adjacency +=
        static_cast<long long>(m.normal_adjacency.triangles.size()) * c.copies;
    triangles += static_cast<long long>(m.triangles.rows()) * c.copies;
    one_diagonal = one_diagonal && m.vertex_diagonals.empty() &&
                   m.diagonal == parts[0].mesh->diagonal;
  }
  const long long kMax = std::numeric_limits<int>::max();
  for (const auto& [count, what] :
       {std::pair{vertices, "vertices"}, std::pair{fields, "fields"},
        std::pair{ring_entries, "one-ring entries"},
        std::pair{adjacency, "adjacency entries"},
        std::pair{triangles, "triangles"}})
    if (count > kMax)
      invalid("concatenateTrackingMeshes: " + std::to_string(count) + " " +
              what + " are more than an int can index");

  TrackingMesh out;
  out.field_count = static_cast<int>(fields);
  // The lengths of tracking follow each character's size: one diagonal
  // where every part has the same, else one per vertex.
  out.diagonal = parts[0].mesh->diagonal;
  out.rings.offsets.push_back(0);
  out.normal_adjacency.offsets.push_back(0);
  out.triangles.resize(static_cast<Eigen::Index>(triangles), 3);
  int v0 = 0, field0 = 0, joint0 = 0, f0 = 0;
  for (const TrackingMeshCopies& c : parts) {
    const TrackingMesh& m = *c.mesh;
    const int v = m.vertexCount();
    const int f = static_cast<int>(m.triangles.rows());
    auto shift = [](const std::vector<int>& indices, int by,
                    std::vector<int>& to) {
      for (const int i : indices) to.push_back(i >= 0 ? i + by : i);
    };
    auto append = [](const auto& values, auto& to) {
      to.insert(to.end(), values.begin(), values.end());
    };
    for (int copy = 0; copy < c.copies; ++copy) {
      shift(m.rings.representative, v0, out.rings.representative);
      shift(m.rings.neighbours, v0, out.rings.neighbours);
      append(m.rings.kinds, out.rings.kinds);
      const uint32_t ring0 = out.rings.offsets.back();
      for (int k = 1; k <= v; ++k)
        out.rings.offsets.push_back(m.rings.offsets[k] + ring0);
      append(m.relaxation.weights, out.relaxation.weights);
      append(m.relaxation.rules, out.relaxation.rules);
      append(m.iso_values, out.iso_values);
      shift(m.home_field, field0, out.home_field);
      append(m.home_margin, out.home_margin);
      append(m.home_surface, out.home_surface);
      for (TrackingMesh::PartnerPair pair : m.partner_pairs) {
        pair.field_a += field0;
        pair.field_b += field0;
        pair.joint_a += joint0;
        pair.joint_b += joint0;
        out.partner_pairs.push_back(pair);
      }
      shift(m.rest_crease, static_cast<int>(out.rest_crease_pairs.size()),
            out.rest_crease);
      for (TrackingMesh::CreasePair pair : m.rest_crease_pairs) {
        pair.home_field += field0;
        pair.other_field += field0;
        pair.home_joint += joint0;
        pair.other_joint += joint0;
        out.rest_crease_pairs.push_back(pair);
      }
      append(m.ring_lengths, out.ring_lengths);
      out.triangles.middleRows(f0, f) = m.triangles.array() + v0;
      const uint32_t adjacency0 =
          static_cast<uint32_t>(out.normal_adjacency.triangles.size());
      for (int k = 1; k <= v; ++k)
        out.normal_adjacency.offsets.push_back(m.normal_adjacency.offsets[k] +
                                               adjacency0);
      for (const uint32_t t : m.normal_adjacency.triangles)
        out.normal_adjacency.triangles.push_back(t + f0);
      if (!one_diagonal)
        for (int k = 0; k < v; ++k)
          out.vertex_diagonals.push_back(m.diagonalOf(k));
      // Copy by copy, each in its own march order: by home field (copy
      // i's after copy i - 1's), then along the Morton curve.
      shift(m.march_order, v0, out.march_order);
      for (DislocationCandidate candidate : m.dislocation_candidates) {
        candidate.vertex += v0;
        candidate.home_joint += joint0;
        candidate.other_joint += joint0;
        out.dislocation_candidates.push_back(candidate);
      }
      // Volume restoration: each copy's groups, after the others'.
      TrackingMesh::VolumeGroups& groups = out.volume_groups;
      const int group0 = groups.groupCount();
      const int triangle0 =
          groups.triangle_offsets.empty() ? 0 : groups.triangle_offsets.back();
      if (groups.triangle_offsets.empty()) groups.triangle_offsets.push_back(0);
      shift(m.volume_groups.corners, v0, groups.corners);
      for (size_t g = 1; g < m.volume_groups.triangle_offsets.size(); ++g)
        groups.triangle_offsets.push_back(m.volume_groups.triangle_offsets[g] +
                                          triangle0);
      append(m.volume_groups.rest_volume, groups.rest_volume);
      if (static_cast<int>(m.volume_groups.vertex_group.size()) == v &&
          static_cast<int>(m.volume_groups.vertex_area.size()) == v &&
          static_cast<int>(m.volume_groups.normal_sign.size()) == v) {
        for (const int g : m.volume_groups.vertex_group)
          groups.vertex_group.push_back(g >= 0 ? g + group0 : -1);
        append(m.volume_groups.vertex_area, groups.vertex_area);
        append(m.volume_groups.normal_sign, groups.normal_sign);
      } else {  // no groups in this copy
        groups.vertex_group.insert(groups.vertex_group.end(), v, -1);
        groups.vertex_area.insert(groups.vertex_area.end(), v, 0.f);
        groups.normal_sign.insert(groups.normal_sign.end(), v, 1.f);
      }
      // Near another component of its own copy (the copies' rest poses may
      // overlap: that is the crowd's contact, not a piece of the character).
      if (static_cast<int>(m.volume_groups.near_other.size()) == v)
        append(m.volume_groups.near_other, groups.near_other);
      else
        groups.near_other.insert(groups.near_other.end(), v, 0);
      v0 += v;
      field0 += m.field_count;
      joint0 += c.joints_per_copy;
      f0 += f;
    }
  }
  return out;
}

TrackingMesh replicateTrackingMesh(const TrackingMesh& mesh, int copies,
                                   int joints_per_copy) {
  if (copies < 1)
    invalid("replicateTrackingMesh: " + std::to_string(copies) +
            " copies, expected at least 1");
  return concatenateTrackingMeshes({{&mesh, copies, joints_per_copy}});
}

struct ImplicitCrowd::State {
  struct Character {
    std::shared_ptr<const ImplicitFields> fields;
    int instances = 0, vertices = 0, joints = 0;
    std::vector<std::string> joint_names;
  };
  std::vector<Character> characters;
  // Per instance: its character, first result row and first joint.
  std::vector<int> character_of, first_vertex, first_joint;
  int instances = 0, vertices = 0, joints = 0;  // all instances'
  // The device parts, shared with ImplicitSkinner (frame_pipeline.hpp).
  std::unique_ptr<detail::DeviceFramePipeline> pipeline;
  TransformList staging;  // every instance's transforms, one after another
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
    : ImplicitCrowd(std::move(context), {{&rig, std::move(fields), instances}},
                    options) {}

ImplicitCrowd::ImplicitCrowd(std::shared_ptr<ClContext> context,
                             const std::vector<CrowdCharacter>& characters,
                             const ImplicitSkinnerOptions& options)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  if (characters.empty()) invalid("ImplicitCrowd: no characters");
  // "character c: " where there are several.
  auto where = [&](size_t c) {
    return characters.size() > 1 ? "character " + std::to_string(c) + ": "
                                 : std::string();
  };
  long long fields_total = 0;
  for (size_t c = 0; c < characters.size(); ++c) {
    const CrowdCharacter& ch = characters[c];
    if (ch.instances < 1)
      invalid("ImplicitCrowd: " + where(c) + std::to_string(ch.instances) +
              " instances, expected at least 1");
    if (!ch.rig) invalid("ImplicitCrowd: " + where(c) + "no rig");
    if (!ch.fields) invalid("ImplicitCrowd: " + where(c) + "no fields");
    fields_total +=
        static_cast<long long>(ch.fields->grids.fieldCount()) * ch.instances;
  }
  if (!context) invalid("ImplicitCrowd: no context");
  options.validate().throwIfFailed("ImplicitSkinnerOptions");
  if (options.tracking_mode != TrackingMode::k2013)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("ImplicitCrowd: tracking mode ") +
                    trackingModeName(options.tracking_mode) +
                    " is not supported: a crowd tracks in the 2013 mode");
  for (size_t c = 0; c < characters.size(); ++c) {
    const Rig& rig = *characters[c].rig;
    rig.validate().throwIfFailed(rig.source);
    if (const Validation v = fieldsFitRig(*characters[c].fields, rig); !v)
      invalid("ImplicitCrowd: " + where(c) + v.reason());
  }
  // The neighbourhood lists tag a field index in 16 bits.
  constexpr int kMaxFields = FieldNeighbourhoods::kFieldMask;
  if (fields_total > kMaxFields) {
    std::string counts;
    for (const CrowdCharacter& ch : characters)
      counts += (counts.empty() ? "" : " and ") + std::to_string(ch.instances) +
                " instances of " +
                std::to_string(ch.fields->grids.fieldCount()) + " fields";
    invalid("ImplicitCrowd: " + counts + " are more than the " +
            std::to_string(kMaxFields) + " fields a crowd can hold");
  }
  long long vertices = 0, joints = 0, influences = 0;
  std::vector<TrackingMesh> ones;  // one instance's tracking mesh each
  ones.reserve(characters.size());
  std::vector<TrackingMeshCopies> tracking_parts;
  std::vector<Copies> skinning_parts;
  std::vector<ClFieldEvaluation::FieldGroup> field_groups;
  for (size_t c = 0; c < characters.size(); ++c) {
    const CrowdCharacter& ch = characters[c];
    const Rig& rig = *ch.rig;
    State::Character character;
    character.fields = ch.fields;
    character.instances = ch.instances;
    character.vertices = rig.mesh.vertexCount();
    character.joints = rig.skeleton.jointCount();
    for (const Joint& j : rig.skeleton.joints)
      character.joint_names.push_back(j.name);
    for (int i = 0; i < ch.instances; ++i) {
      s.character_of.push_back(static_cast<int>(c));
      s.first_vertex.push_back(static_cast<int>(
          std::min<long long>(vertices, std::numeric_limits<int>::max())));
      s.first_joint.push_back(static_cast<int>(
          std::min<long long>(joints, std::numeric_limits<int>::max())));
      vertices += character.vertices;
      joints += character.joints;
      influences += static_cast<long long>(rig.weights.joints.size());
    }
    for (const auto& [count, what] :
         {std::pair{vertices, "vertices"}, std::pair{joints, "joints"},
          std::pair{influences, "skin influences"}})
      if (count > std::numeric_limits<int>::max())
        invalid("ImplicitCrowd: " + std::to_string(count) + " " + what +
                " in all are more than an int can index");
    ones.push_back(detail::buildSkinnerTrackingMesh(rig, *ch.fields));
    tracking_parts.push_back({&ones.back(), ch.instances, character.joints});
    skinning_parts.push_back(
        {&rig.mesh, &rig.weights, ch.instances, character.joints});
    // Each character's grids once, shared by its instances.
    field_groups.push_back({&ch.fields->grids, character.joints,
                            &ch.fields->composition, ch.instances});
    s.characters.push_back(std::move(character));
  }
  s.instances = static_cast<int>(s.character_of.size());
  s.vertices = static_cast<int>(vertices);
  s.joints = static_cast<int>(joints);
  TrackingMesh tracking_mesh = concatenateTrackingMeshes(tracking_parts);
  s.pipeline = std::make_unique<detail::DeviceFramePipeline>(
      std::move(context), concatenatedMesh(skinning_parts),
      concatenatedWeights(skinning_parts), s.joints, field_groups,
      std::move(tracking_mesh), options);
}

ImplicitCrowd::~ImplicitCrowd() = default;
ImplicitCrowd::ImplicitCrowd(ImplicitCrowd&&) noexcept = default;
ImplicitCrowd& ImplicitCrowd::operator=(ImplicitCrowd&&) noexcept = default;

ImplicitCrowd::State& ImplicitCrowd::state(const char* what,
                                           bool needs_run) const {
  detail::checkUsable("ImplicitCrowd", "crowd", what, state_ != nullptr,
                      needs_run, state_ && state_->pipeline->has_run);
  return *state_;
}

void ImplicitCrowd::run(const std::vector<TransformList>& skinning) {
  State& s = state("run", false);
  if (static_cast<int>(skinning.size()) != s.instances)
    invalid("ImplicitCrowd::run: " + std::to_string(skinning.size()) +
            " poses given for a crowd of " + std::to_string(s.instances) +
            " instances");
  s.staging.clear();
  s.staging.reserve(static_cast<size_t>(s.joints));
  for (int i = 0; i < s.instances; ++i) {
    const State::Character& character = s.characters[s.character_of[i]];
    const TransformList& pose = skinning[i];
    if (static_cast<int>(pose.size()) != character.joints)
      invalid("ImplicitCrowd::run: instance " + std::to_string(i) + ": " +
              std::to_string(pose.size()) +
              " joint transforms given for a skeleton of " +
              std::to_string(character.joints) + " joints");
    for (int j = 0; j < character.joints; ++j)
      if (!pose[j].matrix().allFinite()) {
        const std::string& name = character.joint_names[j];
        invalid("ImplicitCrowd::run: instance " + std::to_string(i) +
                ": the transform of joint " + std::to_string(j) +
                (name.empty() ? "" : " '" + name + "'") + " is not finite");
      }
    s.staging.insert(s.staging.end(), pose.begin(), pose.end());
  }
  s.pipeline->run(s.staging);
}

void ImplicitCrowd::readPositions(Matrix3Xf& out) {
  state("readPositions", true).pipeline->readPositions(out);
}

void ImplicitCrowd::readNormals(Matrix3Xf& out) {
  state("readNormals", true).pipeline->readNormals(out);
}

const cl::Buffer& ImplicitCrowd::positionsBuffer() const {
  return state("positionsBuffer", false).pipeline->tracking->positionsBuffer();
}
const cl::Buffer& ImplicitCrowd::normalsBuffer() const {
  return state("normalsBuffer", false).pipeline->tracking->normalsBuffer();
}
int ImplicitCrowd::contactCount() {
  return state("contactCount", true).pipeline->tracking->contactCount();
}
const ImplicitStageTimes& ImplicitCrowd::lastTimes() const {
  return state("lastTimes", false).pipeline->times;
}
const TrackingMesh& ImplicitCrowd::trackingMesh() const {
  return *state("trackingMesh", false).pipeline->tracking_mesh;
}
ClSurfaceTracking& ImplicitCrowd::tracking() {
  return *state("tracking", false).pipeline->tracking;
}
ClFieldEvaluation& ImplicitCrowd::fieldEvaluation() {
  return *state("fieldEvaluation", false).pipeline->field_evaluation;
}
const ImplicitSkinnerOptions& ImplicitCrowd::options() const {
  return state("options", false).pipeline->options;
}
int ImplicitCrowd::instanceCount() const {
  return state("instanceCount", false).instances;
}
int ImplicitCrowd::character(const char* what, int c) const {
  const State& s = state(what, false);
  if (c < 0 || c >= static_cast<int>(s.characters.size()))
    invalid(std::string("ImplicitCrowd::") + what + ": character " +
            std::to_string(c) + " of a crowd of " +
            std::to_string(s.characters.size()));
  return c;
}
int ImplicitCrowd::instance(const char* what, int i) const {
  const State& s = state(what, false);
  if (i < 0 || i >= s.instances)
    invalid(std::string("ImplicitCrowd::") + what + ": instance " +
            std::to_string(i) + " of a crowd of " +
            std::to_string(s.instances));
  return i;
}
int ImplicitCrowd::characterCount() const {
  return static_cast<int>(state("characterCount", false).characters.size());
}
const ImplicitFields& ImplicitCrowd::fields(int c) const {
  return *state_->characters[character("fields", c)].fields;
}
int ImplicitCrowd::vertexCount(int c) const {
  return state_->characters[character("vertexCount", c)].vertices;
}
int ImplicitCrowd::jointCount(int c) const {
  return state_->characters[character("jointCount", c)].joints;
}
int ImplicitCrowd::totalVertexCount() const {
  return state("totalVertexCount", false).vertices;
}
int ImplicitCrowd::characterOf(int i) const {
  return state_->character_of[instance("characterOf", i)];
}
int ImplicitCrowd::instanceFirstVertex(int i) const {
  return state_->first_vertex[instance("instanceFirstVertex", i)];
}
int ImplicitCrowd::instanceFirstJoint(int i) const {
  return state_->first_joint[instance("instanceFirstJoint", i)];
}

}  // namespace isk
