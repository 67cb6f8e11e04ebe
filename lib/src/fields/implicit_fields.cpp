#include "isk/fields/implicit_fields.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <filesystem>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/parallel_for.hpp"
#include "isk/core/error.hpp"
#include "isk/core/one_ring.hpp"
#include "isk/core/stopwatch.hpp"
#include "isk/core/surface_orientation.hpp"
#include "isk/fields/field_cache.hpp"

namespace isk {
namespace {

using detail::parallelFor;

// The part's vertices with their geometric normals, as samples: the last
// resort for parts too small for Poisson-disk sampling.
HermiteSamples vertexSamples(const Mesh& mesh, const BonePartition& partition,
                             int joint, const SurfaceOrientation& orientation) {
  std::vector<Eigen::Vector3d> normals(mesh.vertexCount(),
                                       Eigen::Vector3d::Zero());
  for (int t : partition.part_triangles[joint]) {
    const Eigen::Vector3d a =
        mesh.positions.row(mesh.triangles(t, 0)).transpose().cast<double>();
    const Eigen::Vector3d b =
        mesh.positions.row(mesh.triangles(t, 1)).transpose().cast<double>();
    const Eigen::Vector3d c =
        mesh.positions.row(mesh.triangles(t, 2)).transpose().cast<double>();
    const Eigen::Vector3d n =
        (b - a).cross(c - a) * orientation.triangle_sign[t];
    for (int i = 0; i < 3; ++i) normals[mesh.triangles(t, i)] += n;
  }
  // Vertices split along seams share a position: one sample each, with the
  // summed normal.
  std::map<std::array<float, 3>, Eigen::Vector3d> by_position;
  for (int v : partition.part_vertices[joint]) {
    if (!partition.vertex_layer.empty() && partition.vertex_layer[v]) continue;
    Eigen::Vector3d n = normals[v];
    if (!(n.norm() > 0)) n = mesh.normals.row(v).transpose().cast<double>();
    if (!(n.norm() > 0) || !n.allFinite()) continue;
    const std::array<float, 3> key = {
        mesh.positions(v, 0), mesh.positions(v, 1), mesh.positions(v, 2)};
    auto it = by_position.emplace(key, Eigen::Vector3d::Zero()).first;
    it->second += n.normalized();
  }
  HermiteSamples s;
  for (const auto& [key, n] : by_position) {
    if (!(n.norm() > 1e-9)) continue;
    s.positions.push_back(Eigen::Vector3d(key[0], key[1], key[2]));
    s.normals.push_back(n.normalized());
  }
  return s;
}

// What every stage of one build reads.
struct BuildInputs {
  const Rig& rig;
  const ImplicitFieldsOptions& options;
  int threads;  // resolved: never 0

  void report(const char* stage, float fraction) const {
    if (options.progress) options.progress(stage, fraction);
  }
};

// Throws isk::Error(kInvalidArgument) naming the first bad option, or the
// rig's first problem.
void checkBuildInputs(const Rig& rig, const ImplicitFieldsOptions& options) {
  // 256^3 float4 is already 256 MiB per bone.
  if (options.grid_resolution < 2 || options.grid_resolution > 256)
    throw Error(
        ErrorCode::kInvalidArgument,
        "buildImplicitFields: grid_resolution must be in [2, 256], got " +
            std::to_string(options.grid_resolution));
  if (options.sampling.target_samples < 1)
    throw Error(ErrorCode::kInvalidArgument,
                "buildImplicitFields: target_samples must be at least 1");
  if (!(options.sampling.culling_h >= 0 && options.sampling.culling_h < 0.5))
    throw Error(ErrorCode::kInvalidArgument,
                "buildImplicitFields: culling_h must be in [0, 0.5)");
  if (options.grid_precision != GridPrecision::kFloat &&
      options.grid_precision != GridPrecision::kHalf)
    throw Error(ErrorCode::kInvalidArgument,
                "buildImplicitFields: grid_precision must be kFloat or kHalf, "
                "got " +
                    std::to_string(static_cast<int>(options.grid_precision)));
  // The rig first, named by its source (partitionMesh validates it again).
  rig.validate().throwIfFailed("buildImplicitFields: " + rig.source);
  for (const auto& [name, samples] : options.joint_samples) {
    if (rig.skeleton.find(name) < 0)
      throw Error(ErrorCode::kInvalidArgument,
                  "buildImplicitFields: joint_samples names joint '" + name +
                      "', which the skeleton does not have");
    if (samples < 1 || samples > 100000)
      throw Error(ErrorCode::kInvalidArgument,
                  "buildImplicitFields: joint_samples['" + name +
                      "'] must be in [1, 100000], got " +
                      std::to_string(samples));
  }
  for (const std::string& name : options.untracked_joints)
    if (rig.skeleton.find(name) < 0)
      throw Error(ErrorCode::kInvalidArgument,
                  "buildImplicitFields: untracked_joints names joint '" + name +
                      "', which the skeleton does not have");
  validateCompositionOptions(rig.skeleton, options.composition)
      .throwIfFailed("buildImplicitFields");
}

// One mesh part per bone; its warnings start the build's.
void partitionStage(const BuildInputs& in, ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  in.report("partition", 0);
  out.partition = partitionMesh(in.rig);
  BonePartition& partition = out.partition;
  if (!in.options.sampling.skin_only) {  // layers fitted with their skin
    for (size_t j = 0; j < partition.layer_triangles.size(); ++j) {
      std::vector<int>& part = partition.part_triangles[j];
      part.insert(part.end(), partition.layer_triangles[j].begin(),
                  partition.layer_triangles[j].end());
      std::sort(part.begin(), part.end());
      partition.layer_triangles[j].clear();
    }
    std::fill(partition.vertex_layer.begin(), partition.vertex_layer.end(), 0);
  }
  out.warnings = partition.warnings;
  in.report("partition", 1);
  out.times.partition_ms = millisecondsSince(start);
}

// The cache file of this rig and these options; empty when no cache is
// asked for or none can be kept (edited samples cannot be part of a key).
std::string fieldCachePath(const BuildInputs& in) {
  if (!in.options.cache || in.options.edit_samples) return "";
  const std::string folder = in.options.cache_folder.empty()
                                 ? operatorTableCacheFolder()
                                 : in.options.cache_folder;
  if (folder.empty()) return "";
  return (std::filesystem::path(folder) /
          fieldCacheFileName(in.rig, in.options))
      .string();
}

// The samples, fits and grids from the cache file at `cache_path`, when a
// valid one is there. A file that is there but unusable leaves its reason
// in out.cache_note and in *cache_warnings.
bool cacheLoadStage(const BuildInputs& in, const std::string& cache_path,
                    ImplicitFields& out,
                    std::vector<std::string>* cache_warnings) {
  if (cache_path.empty()) return false;
  out.cache_file = cache_path;
  out.cache_origin = FieldCacheOrigin::kBuilt;
  std::error_code ec;
  if (!std::filesystem::exists(std::filesystem::symlink_status(cache_path, ec)))
    return false;
  const auto start = std::chrono::steady_clock::now();
  in.report("loading", 0);
  std::string why;
  if (!loadFieldCache(cache_path, in.rig, in.options, &out, &why)) {
    out.cache_origin = FieldCacheOrigin::kRebuilt;
    out.cache_note = why;
    out.warnings = out.partition.warnings;
    cache_warnings->push_back("field cache unusable (" + why +
                              "); building the fields again");
    return false;
  }
  out.cache_origin = FieldCacheOrigin::kLoaded;
  out.times.sampling_ms = millisecondsSince(start);
  in.report("loading", 1);
  return true;
}

// Poisson-disk samples of every part (section 4.1), with the fallbacks of
// the header comment, then the application's edits.
std::vector<BoneSamples> samplingStage(const BuildInputs& in,
                                       ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  const Skeleton& skeleton = in.rig.skeleton;
  const std::vector<int>& joints = out.partition.field_joints;
  std::vector<BoneSamples> samples(joints.size());
  const Mesh& mesh = in.rig.mesh;
  const SurfaceOrientation orientation = SurfaceOrientation::of(mesh);
  for (const SurfaceOrientation::InsideOut& c : orientation.inside_out)
    out.warnings.push_back(
        "the closed surface through " + mesh.describeVertex(c.vertex) + " (" +
        std::to_string(c.triangle_count) +
        " triangles) is wound inside out (its triangles face inwards): its "
        "fields are fitted to its outward side");
  for (size_t i = 0; i < joints.size(); ++i) {
    const int j = joints[i];
    const std::string name = "joint '" + skeleton.joints[j].name + "'";
    BoneSamplingOptions sampling = in.options.sampling;
    if (const auto it = in.options.joint_samples.find(skeleton.joints[j].name);
        it != in.options.joint_samples.end())
      sampling.target_samples = it->second;
    samples[i] = sampleBonePart(mesh, out.partition, j, sampling, &orientation);
    if (samples[i].all().size() < 4 && samples[i].culled > 0) {
      BoneSamplingOptions uncut = sampling;
      uncut.culling_h = 0;
      samples[i] = sampleBonePart(mesh, out.partition, j, uncut, &orientation);
      out.warnings.push_back(name +
                             ": fewer than 4 samples after culling; "
                             "sampled without culling planes");
    }
    if (samples[i].all().size() < 4) {
      samples[i].surface = vertexSamples(mesh, out.partition, j, orientation);
      out.warnings.push_back(
          name + ": part too small for Poisson-disk sampling (" +
          std::to_string(out.partition.part_vertices[j].size()) +
          " vertices); its vertices are the samples");
    }
    in.report("sampling", static_cast<float>(i + 1) / joints.size());
  }
  if (in.options.edit_samples) in.options.edit_samples(samples);
  out.times.sampling_ms = millisecondsSince(start);
  return samples;
}

// One HRBF fit per part (eq. 1), in parallel; a part whose fit fails gets
// no field (and its samples are dropped with it), with a warning.
void fittingStage(const BuildInputs& in, std::vector<BoneSamples> samples,
                  ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<BoneField> fields(samples.size());
  std::vector<std::vector<std::string>> fit_warnings(samples.size());
  std::vector<char> fitted(samples.size(), 0);
  parallelFor(
      static_cast<int>(samples.size()), in.threads,
      [&](int i) {
        try {
          fields[i] = fitBoneField(in.rig.skeleton, in.rig.mesh.positions,
                                   out.partition, samples[i], &fit_warnings[i]);
          fitted[i] = 1;
        } catch (const Error& e) {
          fit_warnings[i].push_back(std::string(e.what()) +
                                    "; this bone gets no field");
        }
      },
      [&](float f) { in.report("fitting", f); });
  for (size_t i = 0; i < samples.size(); ++i) {
    out.warnings.insert(out.warnings.end(), fit_warnings[i].begin(),
                        fit_warnings[i].end());
    if (!fitted[i]) continue;
    out.samples.push_back(std::move(samples[i]));
    out.fields.push_back(std::move(fields[i]));
  }
  out.times.fitting_ms = millisecondsSince(start);
}

// Every field baked into its N^3 grid, in parallel.
void bakingStage(const BuildInputs& in, ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  const int resolution = in.options.grid_resolution;
  out.grids.resolution = resolution;
  out.grids.grids.resize(out.fields.size());
  parallelFor(
      static_cast<int>(out.fields.size()), in.threads,
      [&](int i) { out.grids.grids[i] = bakeField(out.fields[i], resolution); },
      [&](float f) { in.report("baking", f); });
  out.grids.field_of_joint.assign(in.rig.skeleton.jointCount(), -1);
  for (int i = 0; i < out.grids.fieldCount(); ++i)
    out.grids.field_of_joint[out.grids.grids[i].joint] = i;
  out.times.baking_ms = millisecondsSince(start);
}

// Writes what was just built to `cache_path` (none: nothing); a failure is
// a warning, never an error.
void cacheSaveStage(const BuildInputs& in, const std::string& cache_path,
                    const ImplicitFields& out,
                    std::vector<std::string>* cache_warnings) {
  if (cache_path.empty()) return;
  std::string why;
  if (!saveFieldCache(out, in.rig, in.options, cache_path, &why))
    cache_warnings->push_back("could not write the field cache (" + why +
                              "); the fields will be built again next time");
}

// The operator of each joint pair and its tables (section 4.2).
void operatorsStage(const BuildInputs& in, ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  in.report("operators", 0);
  out.composition =
      buildComposition(in.rig.skeleton, out.grids, in.options.composition,
                       [&](float f) { in.report("operators", f); });
  out.warnings.insert(out.warnings.end(), out.composition.warnings.begin(),
                      out.composition.warnings.end());
  out.times.operators_ms = millisecondsSince(start);
}

// Half-precision grids are rounded before the iso values are taken, so
// that the rest pose lies on the iso-surfaces of the grids evaluated.
void precisionStage(const BuildInputs& in, ImplicitFields& out) {
  if (in.options.grid_precision == GridPrecision::kHalf)
    roundGridsToHalf(out.grids);
}

// The vertices whose part belongs to one of `names` (ascending).
std::vector<int> untrackedVertices(const Rig& rig,
                                   const BonePartition& partition,
                                   const std::set<std::string>& names) {
  std::vector<int> out;
  if (names.empty()) return out;
  std::vector<uint8_t> untracked(rig.skeleton.jointCount(), 0);
  for (const std::string& name : names)
    if (const int j = rig.skeleton.find(name); j >= 0) untracked[j] = 1;
  for (size_t v = 0; v < partition.vertex_joint.size(); ++v) {
    const int j = partition.vertex_joint[v];
    if (j >= 0 && j < static_cast<int>(untracked.size()) && untracked[j])
      out.push_back(static_cast<int>(v));
  }
  return out;
}

// untracked_joints' vertices and the rigid pieces' (when the mode keeps
// them rigid), merged ascending; `rigid` receives the latter.
std::vector<int> untrackedAndRigid(const Rig& rig,
                                   const BonePartition& partition,
                                   const ImplicitFieldsOptions& options,
                                   std::vector<int>* rigid) {
  std::vector<int> out =
      untrackedVertices(rig, partition, options.untracked_joints);
  rigid->clear();
  if (options.rigid_pieces == RigidPieces::kTracked) return out;
  std::vector<int> pieces = rigidPieceVertices(rig);
  const bool keep =
      options.rigid_pieces == RigidPieces::kRigid ||
      (rig.mesh.vertexCount() > 0 &&
       static_cast<float>(pieces.size()) >=
           kRigidCharacterShare * static_cast<float>(rig.mesh.vertexCount()));
  if (!keep) return out;
  *rigid = std::move(pieces);
  std::vector<int> merged;
  std::set_union(out.begin(), out.end(), rigid->begin(), rigid->end(),
                 std::back_inserter(merged));
  return merged;
}

void zeroIsoValues(const std::vector<int>& vertices,
                   std::vector<float>& iso_values) {
  for (const int v : vertices) iso_values[v] = 0.f;
}

// Each vertex's composed field value at the bind pose: the value tracking
// brings it back to (0 on the untracked joints' parts).
void isoValuesStage(const BuildInputs& in, ImplicitFields& out) {
  const auto start = std::chrono::steady_clock::now();
  in.report("iso values", 0);
  out.iso_values = computeIsoValues(out.grids, in.rig.mesh.positions,
                                    &out.composition, &out.outside_vertices);
  out.untracked_vertices = untrackedAndRigid(in.rig, out.partition, in.options,
                                             &out.rigid_piece_vertices);
  zeroIsoValues(out.untracked_vertices, out.iso_values);
  if (!out.outside_vertices.empty())
    out.warnings.push_back(
        std::to_string(out.outside_vertices.size()) +
        " vertices lie outside every field's support (first: vertex " +
        std::to_string(out.outside_vertices.front()) + " of " +
        in.rig.mesh.describeVertex(out.outside_vertices.front()) +
        "); surface tracking leaves them where skinning puts them");
  in.report("iso values", 1);
  out.times.iso_ms = millisecondsSince(start);
}

}  // namespace

const char* fieldCacheOriginName(FieldCacheOrigin origin) {
  switch (origin) {
    case FieldCacheOrigin::kOff:
      return "off";
    case FieldCacheOrigin::kBuilt:
      return "built";
    case FieldCacheOrigin::kLoaded:
      return "loaded";
    case FieldCacheOrigin::kRebuilt:
      return "rebuilt";
  }
  return "?";
}

ImplicitFields buildImplicitFields(const Rig& rig,
                                   const ImplicitFieldsOptions& options) {
  checkBuildInputs(rig, options);
  const BuildInputs in{rig, options, detail::threadCount(options.threads)};
  ImplicitFields out;
  partitionStage(in, out);
  // Samples, fits and grids: from the cache when it holds them.
  const std::string cache_path = fieldCachePath(in);
  std::vector<std::string> cache_warnings;
  if (!cacheLoadStage(in, cache_path, out, &cache_warnings)) {
    std::vector<BoneSamples> samples = samplingStage(in, out);
    fittingStage(in, std::move(samples), out);
    bakingStage(in, out);
    cacheSaveStage(in, cache_path, out, &cache_warnings);
  }
  // After the save: a file keeps the warnings of its build, not of its
  // cache's own trouble.
  out.warnings.insert(out.warnings.end(), cache_warnings.begin(),
                      cache_warnings.end());
  operatorsStage(in, out);
  precisionStage(in, out);
  isoValuesStage(in, out);
  return out;
}

void useHalfPrecisionGrids(ImplicitFields& fields, const Rig& rig) {
  if (fields.grids.precision == GridPrecision::kHalf) return;
  if (static_cast<int>(fields.iso_values.size()) != rig.mesh.vertexCount())
    throw Error(ErrorCode::kInvalidArgument,
                "useHalfPrecisionGrids: the fields have " +
                    std::to_string(fields.iso_values.size()) +
                    " iso values, the rig's mesh " +
                    std::to_string(rig.mesh.vertexCount()) + " vertices");
  FieldGridSet rounded = fields.grids;
  roundGridsToHalf(rounded);
  std::vector<int> outside;
  std::vector<float> iso = computeIsoValues(rounded, rig.mesh.positions,
                                            &fields.composition, &outside);
  zeroIsoValues(fields.untracked_vertices, iso);
  fields.grids = std::move(rounded);
  fields.iso_values = std::move(iso);
  fields.outside_vertices = std::move(outside);
}

const char* rigidPiecesName(RigidPieces mode) {
  switch (mode) {
    case RigidPieces::kAuto:
      return "auto";
    case RigidPieces::kRigid:
      return "rigid";
    case RigidPieces::kTracked:
      return "tracked";
  }
  return "?";
}

bool parseRigidPieces(const std::string& name, RigidPieces* mode) {
  for (const RigidPieces m :
       {RigidPieces::kAuto, RigidPieces::kRigid, RigidPieces::kTracked}) {
    if (name == rigidPiecesName(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

std::vector<int> rigidPieceVertices(const Rig& rig) {
  const Mesh& mesh = rig.mesh;
  const int n = mesh.vertexCount();
  const SkinWeights& weights = rig.weights;
  if (weights.vertexCount() != n) return {};
  // Connected components of the welded mesh (union-find over triangles).
  const std::vector<int> welded = weldedRepresentatives(mesh.positions);
  std::vector<int> parent(n);
  for (int v = 0; v < n; ++v) parent[v] = v;
  auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  auto join = [&](int a, int b) {
    a = root(a), b = root(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  for (int v = 0; v < n; ++v) join(v, welded[v]);
  for (Eigen::Index f = 0; f < mesh.triangles.rows(); ++f) {
    join(mesh.triangles(f, 0), mesh.triangles(f, 1));
    join(mesh.triangles(f, 1), mesh.triangles(f, 2));
  }
  // Per component: its one joint, or -1 once a vertex is blended or bound
  // to another joint.
  constexpr int kNone = -2;
  std::vector<int> joint(n, kNone);
  for (int v = 0; v < n; ++v) {
    int bound = -1;
    for (uint32_t i = weights.offsets[v]; i < weights.offsets[v + 1]; ++i)
      if (weights.weights[i] >= kRigidPieceWeight)
        bound = static_cast<int>(weights.joints[i]);
    int& j = joint[root(v)];
    if (bound < 0 || (j != kNone && j != bound))
      j = -1;
    else
      j = bound;
  }
  std::vector<int> out;
  for (int v = 0; v < n; ++v)
    if (joint[root(v)] >= 0) out.push_back(v);
  return out;
}

Validation fieldsFitRig(const ImplicitFields& fields, const Rig& rig) {
  if (static_cast<int>(fields.iso_values.size()) != rig.mesh.vertexCount())
    return Validation::fail("the fields hold " +
                            std::to_string(fields.iso_values.size()) +
                            " iso values but " + rig.source + " has " +
                            std::to_string(rig.mesh.vertexCount()) +
                            " vertices (built for another rig?)");
  for (const FieldGrid& g : fields.grids.grids)
    if (g.joint < 0 || g.joint >= rig.skeleton.jointCount())
      return Validation::fail(
          "a field belongs to joint " + std::to_string(g.joint) + " but " +
          rig.source + " has " + std::to_string(rig.skeleton.jointCount()) +
          " joints (built for another rig?)");
  return Validation::ok();
}

}  // namespace isk
