#include "isk/io/import.hpp"

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <Eigen/SVD>
#include <algorithm>
#include <assimp/Importer.hpp>
#include <assimp/ProgressHandler.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "io/child_process.hpp"
#include "io/rig_serialization.hpp"
#include "isk/core/error.hpp"

namespace isk {
namespace {

using Matrix4d = Eigen::Matrix4d;

// Everything the loader works out about the node tree, in DFS preorder.
struct NodeInfo {
  const aiNode* node = nullptr;
  int parent = -1;  // index in the DFS order, -1 for the scene root
  Matrix4d global;  // scene world transform at the rest pose
  int joint = -1;   // joint index, -1 when not a joint
};

class Loader {
 public:
  Loader(const std::string& path, const ImportOptions& options)
      : path_(path), options_(options) {}

  Rig load();

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(ErrorCode::kMalformedAsset, path_ + ": " + what);
  }
  void warn(const std::string& what) { rig_.warnings.push_back(what); }

  void report(const char* stage, float fraction) const;
  void checkReadable() const;
  void checkFiniteMeshes() const;
  void collectNodes(const aiNode* node, int parent);
  int resolveNode(const std::string& name) const;
  void findMeshNodes();
  void buildSkeleton();
  void checkRigid(const Joint& joint) const;
  void addMesh(unsigned mesh_index);
  void finishNormals();
  void addClip(unsigned index);

  std::string path_;
  ImportOptions options_;
  const aiScene* scene_ = nullptr;
  Rig rig_;

  std::vector<NodeInfo> nodes_;
  std::unordered_map<const aiNode*, int> node_index_;
  std::multimap<std::string, int> nodes_by_name_;
  std::vector<int> mesh_node_;                // per mesh: first node, or -1
  std::vector<int> mesh_instances_;           // per mesh: nodes placing it
  std::map<std::string, int> bone_joint_;     // bone name -> joint index
  std::map<std::string, int> joint_by_name_;  // first joint of each name
  std::vector<bool> has_bind_;                // per joint: bind from a bone
  std::vector<std::vector<std::pair<int, float>>> influences_;
  std::vector<bool> normal_missing_;  // per merged vertex
};

Matrix4d toEigen(const aiMatrix4x4& m) {
  Matrix4d r;
  r << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4,
      m.d1, m.d2, m.d3, m.d4;
  return r;
}

Eigen::Affine3f toAffine(const Matrix4d& m) {
  Eigen::Affine3f a = Eigen::Affine3f::Identity();
  a.matrix().topRows<3>() = m.topRows<3>().cast<float>();
  return a;
}

// Inverse of an affine 4x4 (bottom row 0 0 0 1).
Matrix4d affineInverse(const Matrix4d& m) {
  Matrix4d r = Matrix4d::Identity();
  const Eigen::Matrix3d inv = m.topLeftCorner<3, 3>().inverse();
  r.topLeftCorner<3, 3>() = inv;
  r.topRightCorner<3, 1>() = -inv * m.topRightCorner<3, 1>();
  return r;
}

bool finite(const aiVector3D& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

std::string quoted(const aiString& s) {
  return "'" + std::string(s.C_Str()) + "'";
}

void Loader::checkReadable() const {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(path_, ec);
  if (!fs::exists(status)) {
    throw Error(ErrorCode::kIo, path_ + ": no such file");
  }
  if (fs::is_directory(status)) {
    throw Error(ErrorCode::kIo, path_ + ": is a directory, not a file");
  }
  std::ifstream in(path_, std::ios::binary);
  if (!in) {
    throw Error(ErrorCode::kIo, path_ + ": cannot be opened for reading");
  }
}

// Runs on the scene as read, before post-processing: JoinIdenticalVertices
// merges a NaN vertex into another one, hiding it. Vertex numbers are then
// those of the file.
void Loader::checkFiniteMeshes() const {
  for (unsigned m = 0; m < scene_->mNumMeshes; ++m) {
    const aiMesh* mesh = scene_->mMeshes[m];
    const std::string label = "mesh " + quoted(mesh->mName);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      if (!finite(mesh->mVertices[v])) {
        fail(label + " vertex " + std::to_string(v) +
             " has a non-finite position");
      }
      if (mesh->HasNormals() && !finite(mesh->mNormals[v])) {
        fail(label + " vertex " + std::to_string(v) +
             " has a non-finite normal");
      }
    }
    for (unsigned b = 0; b < mesh->mNumBones; ++b) {
      const aiBone* bone = mesh->mBones[b];
      if (!toEigen(bone->mOffsetMatrix).allFinite()) {
        fail(label + " bone " + quoted(bone->mName) +
             " has a non-finite offset matrix");
      }
      for (unsigned w = 0; w < bone->mNumWeights; ++w) {
        if (!std::isfinite(bone->mWeights[w].mWeight)) {
          fail(label + " vertex " +
               std::to_string(bone->mWeights[w].mVertexId) +
               " has a non-finite weight for bone " + quoted(bone->mName));
        }
      }
    }
  }
}

void Loader::collectNodes(const aiNode* node, int parent) {
  const int index = static_cast<int>(nodes_.size());
  NodeInfo info;
  info.node = node;
  info.parent = parent;
  const Matrix4d local = toEigen(node->mTransformation);
  if (!local.allFinite()) {
    // Checked here for every node: a non-finite transform poisons every
    // global below it, which would surface later as a vague error.
    fail("node " + quoted(node->mName) + " has a non-finite transform");
  }
  info.global = parent < 0 ? local : Matrix4d(nodes_[parent].global * local);
  nodes_.push_back(info);
  node_index_[node] = index;
  nodes_by_name_.emplace(node->mName.C_Str(), index);
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    collectNodes(node->mChildren[c], index);
  }
}

// Node named `name`. Names are not unique in every file (RobotExpressive.glb
// has mesh nodes named like the bones they hang from): prefer a node without
// meshes, then the first in DFS order.
int Loader::resolveNode(const std::string& name) const {
  int best = -1;
  auto range = nodes_by_name_.equal_range(name);
  for (auto it = range.first; it != range.second; ++it) {
    const int n = it->second;
    if (best < 0) best = n;
    const bool n_plain = nodes_[n].node->mNumMeshes == 0;
    const bool best_plain = nodes_[best].node->mNumMeshes == 0;
    if (n_plain && !best_plain) best = n;
    if (n_plain == best_plain && n < best) best = n;
  }
  return best;
}

void Loader::findMeshNodes() {
  mesh_node_.assign(scene_->mNumMeshes, -1);
  mesh_instances_.assign(scene_->mNumMeshes, 0);
  for (size_t n = 0; n < nodes_.size(); ++n) {
    const aiNode* node = nodes_[n].node;
    for (unsigned k = 0; k < node->mNumMeshes; ++k) {
      const unsigned m = node->mMeshes[k];
      if (m >= scene_->mNumMeshes) continue;  // ValidateDS rejects these
      if (mesh_node_[m] < 0) mesh_node_[m] = static_cast<int>(n);
      ++mesh_instances_[m];
    }
  }
}

// Joints are the bone nodes, their ancestors below the scene root and the
// childless mesh-less nodes directly under bones (bone tips). Every ancestor
// of a joint below the root is a joint, so the parent node of each root joint
// is the scene root itself: root_parent is the scene root's transform and a
// root joint's rest_local is its own node transform.
void Loader::buildSkeleton() {
  std::vector<bool> is_bone(nodes_.size(), false);
  std::map<std::string, int> bone_node;
  // Bones named in the skin but absent from the node tree (anim_test.x has
  // two): name -> (mesh, bone) that first gave them.
  std::vector<std::pair<std::string, std::pair<unsigned, unsigned>>> orphans;
  for (unsigned m = 0; m < scene_->mNumMeshes; ++m) {
    const aiMesh* mesh = scene_->mMeshes[m];
    for (unsigned b = 0; b < mesh->mNumBones; ++b) {
      const std::string name = mesh->mBones[b]->mName.C_Str();
      if (bone_node.count(name)) continue;
      const int n = resolveNode(name);
      bone_node[name] = n;
      if (n >= 0) {
        is_bone[n] = true;
      } else {
        orphans.push_back({name, {m, b}});
      }
    }
  }
  if (bone_node.empty()) fail("no skeleton: no mesh has bones");

  std::vector<bool> in_skeleton(nodes_.size(), false);
  for (size_t n = 0; n < nodes_.size(); ++n) {
    if (!is_bone[n]) continue;
    in_skeleton[n] = true;
    for (int a = nodes_[n].parent; a > 0; a = nodes_[a].parent) {
      in_skeleton[a] = true;
    }
    const aiNode* node = nodes_[n].node;
    for (unsigned c = 0; c < node->mNumChildren; ++c) {
      const aiNode* child = node->mChildren[c];
      if (child->mNumChildren == 0 && child->mNumMeshes == 0) {
        in_skeleton[node_index_.at(child)] = true;
      }
    }
  }

  Skeleton& skeleton = rig_.skeleton;
  const Matrix4d root_parent =
      in_skeleton[0] ? Matrix4d::Identity() : nodes_[0].global;
  skeleton.root_parent = toAffine(root_parent);
  for (size_t n = 0; n < nodes_.size(); ++n) {  // DFS order: parents first
    if (!in_skeleton[n]) continue;
    Joint joint;
    joint.name = nodes_[n].node->mName.C_Str();
    const int parent_node = nodes_[n].parent;
    joint.parent = parent_node >= 0 ? nodes_[parent_node].joint : -1;
    joint.rest_local = toAffine(toEigen(nodes_[n].node->mTransformation));
    joint.inverse_bind = toAffine(affineInverse(nodes_[n].global));
    joint.is_skin_joint = is_bone[n];
    nodes_[n].joint = skeleton.jointCount();
    joint_by_name_.emplace(joint.name, skeleton.jointCount());
    skeleton.joints.push_back(joint);
  }
  for (const auto& [name, n] : bone_node) {
    if (n >= 0) bone_joint_[name] = nodes_[n].joint;
  }

  // A bone without a node cannot be animated, but its weights still matter:
  // it becomes a root joint held at its bind pose.
  for (const auto& [name, where] : orphans) {
    const aiMesh* mesh = scene_->mMeshes[where.first];
    const std::string label =
        "bone '" + name + "' of mesh " + quoted(mesh->mName);
    const Matrix4d offset = toEigen(mesh->mBones[where.second]->mOffsetMatrix);
    const int node = mesh_node_[where.first];
    if (!offset.allFinite()) fail(label + " has a non-finite offset matrix");
    if (node < 0) fail(label + " has no node in the scene");
    const Matrix4d bind = nodes_[node].global * affineInverse(offset);
    Joint joint;
    joint.name = name;
    joint.rest_local = toAffine(affineInverse(root_parent) * bind);
    joint.inverse_bind = toAffine(affineInverse(bind));
    joint.is_skin_joint = true;
    bone_joint_[name] = skeleton.jointCount();
    joint_by_name_.emplace(name, skeleton.jointCount());
    skeleton.joints.push_back(joint);
    warn(label +
         " has no node in the scene: added as a root joint fixed at "
         "its bind pose");
  }
  has_bind_.assign(skeleton.joints.size(), false);
}

// The bind global's linear part must be s * R: equal singular values and a
// positive determinant (a unit conversion is fine, a stretch is not).
void Loader::checkRigid(const Joint& joint) const {
  const Eigen::Matrix3d bind =
      joint.inverse_bind.linear().cast<double>().inverse();
  const Eigen::Vector3d sigma =
      Eigen::JacobiSVD<Eigen::Matrix3d>(bind).singularValues();
  if (!(sigma(2) > 0.0) || !std::isfinite(sigma(0))) {
    fail("joint '" + joint.name + "' has a singular bind transform");
  }
  if (sigma(0) - sigma(2) > 1e-3 * sigma(0)) {
    std::ostringstream s;
    s << "joint '" << joint.name
      << "' has a non-uniform scale or shear in its bind transform (scales "
      << sigma(0) << ", " << sigma(1) << ", " << sigma(2) << ")";
    fail(s.str());
  }
  if (bind.determinant() < 0.0) {
    fail("joint '" + joint.name + "' has a mirrored bind transform");
  }
}

void Loader::addMesh(unsigned mesh_index) {
  const aiMesh* mesh = scene_->mMeshes[mesh_index];
  const std::string name = mesh->mName.C_Str();
  const std::string label = "mesh '" + name + "'";
  if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) {
    warn(label + " has only points or lines: skipped");
    return;
  }
  const int node = mesh_node_[mesh_index];
  const int instances = mesh_instances_[mesh_index];
  if (node < 0) {
    warn(label + " is not placed in the scene by any node: skipped");
    return;
  }
  if (instances > 1) {
    warn(label + " is instanced " + std::to_string(instances) +
         " times: only the first instance is used");
  }

  // A mesh without bones follows the nearest joint at or above its node.
  int rigid_joint = -1;
  if (mesh->mNumBones == 0) {
    for (int a = node; a >= 0 && rigid_joint < 0; a = nodes_[a].parent) {
      rigid_joint = nodes_[a].joint;
    }
    if (rigid_joint < 0) {
      warn(label + " has no bones and no joint above it: skipped");
      return;
    }
    warn(label + " has no bones: attached rigidly to joint '" +
         rig_.skeleton.joints[rigid_joint].name + "'");
  }

  const Matrix4d& world = nodes_[node].global;
  const Eigen::Matrix3d linear = world.topLeftCorner<3, 3>();
  const Eigen::Matrix3d normal_matrix = linear.inverse().transpose();
  if (!(std::abs(linear.determinant()) > 0.0) || !normal_matrix.allFinite()) {
    fail(label + " is placed by node " + quoted(nodes_[node].node->mName) +
         " whose transform is singular");
  }
  const bool mirrored = linear.determinant() < 0.0;

  Mesh& out = rig_.mesh;
  const int first_vertex = out.vertexCount();
  const int vertex_count = static_cast<int>(mesh->mNumVertices);
  int triangle_count = 0;
  for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
    triangle_count += mesh->mFaces[f].mNumIndices == 3 ? 1 : 0;
  }
  const int first_triangle = out.triangleCount();
  out.positions.conservativeResize(first_vertex + vertex_count, 3);
  out.normals.conservativeResize(first_vertex + vertex_count, 3);
  out.triangles.conservativeResize(first_triangle + triangle_count, 3);
  normal_missing_.resize(first_vertex + vertex_count, false);
  for (int v = 0; v < vertex_count; ++v) {
    const aiVector3D& p = mesh->mVertices[v];
    const Eigen::Vector3d position =
        linear * Eigen::Vector3d(p.x, p.y, p.z) + world.topRightCorner<3, 1>();
    out.positions.row(first_vertex + v) = position.cast<float>().transpose();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    if (mesh->HasNormals()) {
      const aiVector3D& n = mesh->mNormals[v];
      normal = normal_matrix * Eigen::Vector3d(n.x, n.y, n.z);
    }
    const double length = normal.norm();
    if (length > 1e-12) normal /= length;
    normal_missing_[first_vertex + v] = !(length > 1e-12);
    out.normals.row(first_vertex + v) = normal.cast<float>().transpose();
  }
  int t = first_triangle;
  for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
    const aiFace& face = mesh->mFaces[f];
    if (face.mNumIndices != 3) continue;
    // A mirroring node transform turns the winding inside out: undo it.
    const unsigned b = mirrored ? 2 : 1, c = mirrored ? 1 : 2;
    out.triangles.row(t++) << first_vertex + static_cast<int>(face.mIndices[0]),
        first_vertex + static_cast<int>(face.mIndices[b]),
        first_vertex + static_cast<int>(face.mIndices[c]);
  }
  out.parts.push_back(
      {name, first_vertex, vertex_count, first_triangle, triangle_count});

  influences_.resize(first_vertex + vertex_count);
  if (rigid_joint >= 0) {
    for (int v = 0; v < vertex_count; ++v) {
      influences_[first_vertex + v] = {{rigid_joint, 1.f}};
    }
    rig_.skeleton.joints[rigid_joint].is_skin_joint = true;
    return;
  }

  const Matrix4d world_inverse = affineInverse(world);
  int negative = 0;
  for (unsigned b = 0; b < mesh->mNumBones; ++b) {
    const aiBone* bone = mesh->mBones[b];
    const std::string bone_name = bone->mName.C_Str();
    const int joint = bone_joint_.at(bone_name);
    const Matrix4d offset = toEigen(bone->mOffsetMatrix);
    // Model space -> mesh space -> joint space.
    const Eigen::Affine3f inverse_bind = toAffine(offset * world_inverse);
    Joint& target = rig_.skeleton.joints[joint];
    if (!has_bind_[joint]) {
      target.inverse_bind = inverse_bind;
      has_bind_[joint] = true;
    } else {
      const float scale = target.inverse_bind.matrix().norm();
      const float diff =
          (target.inverse_bind.matrix() - inverse_bind.matrix()).norm();
      if (diff > 1e-4f * scale) {
        warn(label + " gives joint '" + bone_name +
             "' another inverse bind matrix than an earlier mesh: the first "
             "one is kept");
      }
    }
    for (unsigned w = 0; w < bone->mNumWeights; ++w) {
      const aiVertexWeight& vw = bone->mWeights[w];
      if (vw.mVertexId >= mesh->mNumVertices) {
        fail(label + " bone '" + bone_name + "' weights vertex " +
             std::to_string(vw.mVertexId) + " of " +
             std::to_string(mesh->mNumVertices));
      }
      if (vw.mWeight > 0.f) {
        influences_[first_vertex + vw.mVertexId].emplace_back(joint,
                                                              vw.mWeight);
      }
      negative += vw.mWeight < 0.f ? 1 : 0;
    }
  }
  if (negative > 0) {
    warn(label + ": " + std::to_string(negative) + " negative weights dropped");
  }

  int off_count = 0;
  double min_sum = 0.0, max_sum = 0.0;
  for (int v = 0; v < vertex_count; ++v) {
    const auto& list = influences_[first_vertex + v];
    if (list.empty()) {
      fail(label + " vertex " + std::to_string(v) + " has no skin weight");
    }
    double sum = 0.0;
    for (const auto& entry : list) sum += entry.second;
    if (std::abs(sum - 1.0) > options_.weight_sum_tolerance) {
      min_sum = off_count == 0 ? sum : std::min(min_sum, sum);
      max_sum = off_count == 0 ? sum : std::max(max_sum, sum);
      ++off_count;
    }
  }
  if (off_count > 0) {
    std::ostringstream s;
    s << label << ": " << off_count << " of " << vertex_count
      << " vertices had weight sums off 1 (from " << min_sum << " to "
      << max_sum << "): normalized";
    warn(s.str());
  }
}

// Area-weighted normals for vertices that had none (or a zero one).
void Loader::finishNormals() {
  Mesh& mesh = rig_.mesh;
  if (std::find(normal_missing_.begin(), normal_missing_.end(), true) ==
      normal_missing_.end()) {
    return;
  }
  Eigen::MatrixXd accumulated = Eigen::MatrixXd::Zero(mesh.vertexCount(), 3);
  for (int f = 0; f < mesh.triangleCount(); ++f) {
    const Eigen::Vector3d a =
        mesh.positions.row(mesh.triangles(f, 0)).cast<double>();
    const Eigen::Vector3d b =
        mesh.positions.row(mesh.triangles(f, 1)).cast<double>();
    const Eigen::Vector3d c =
        mesh.positions.row(mesh.triangles(f, 2)).cast<double>();
    const Eigen::RowVector3d n = (b - a).cross(c - a).transpose();  // 2 * area
    for (int k = 0; k < 3; ++k) accumulated.row(mesh.triangles(f, k)) += n;
  }
  for (const MeshPart& part : mesh.parts) {
    int missing = 0, unresolved = 0;
    for (int v = part.first_vertex; v < part.first_vertex + part.vertex_count;
         ++v) {
      if (!normal_missing_[v]) continue;
      ++missing;
      const double length = accumulated.row(v).norm();
      if (length > 0.0) {
        mesh.normals.row(v) = (accumulated.row(v) / length).cast<float>();
      } else {
        // Unused or degenerate vertex: any unit vector keeps the mesh valid.
        mesh.normals.row(v) << 0.f, 0.f, 1.f;
        ++unresolved;
      }
    }
    if (missing == 0) continue;
    std::string message = "mesh '" + part.name +
                          "': " + std::to_string(missing) +
                          " vertices had no usable normal: computed from the "
                          "adjacent triangles";
    if (unresolved > 0) {
      message += " (" + std::to_string(unresolved) +
                 " without any non-degenerate triangle got +z)";
    }
    warn(message);
  }
}

void Loader::addClip(unsigned index) {
  const aiAnimation* anim = scene_->mAnimations[index];
  AnimationClip clip;
  clip.name = anim->mName.length > 0 ? std::string(anim->mName.C_Str())
                                     : "clip" + std::to_string(index);
  const std::string label = "clip '" + clip.name + "'";
  const double ticks_per_second =
      anim->mTicksPerSecond > 0.0 ? anim->mTicksPerSecond : 25.0;
  double first = INFINITY, last = -INFINITY;
  auto seconds = [&](double ticks, const std::string& where) {
    const double t = ticks / ticks_per_second;
    if (!std::isfinite(t)) fail(where + " has a non-finite key time");
    first = std::min(first, t);
    last = std::max(last, t);
    return t;
  };
  std::vector<std::string> ignored;
  std::set<int> animated;
  for (unsigned c = 0; c < anim->mNumChannels; ++c) {
    const aiNodeAnim* channel = anim->mChannels[c];
    const std::string node_name = channel->mNodeName.C_Str();
    const auto found = joint_by_name_.find(node_name);
    if (found == joint_by_name_.end()) {
      ignored.push_back(node_name);
      continue;
    }
    if (!animated.insert(found->second).second) {
      warn(label + " animates joint '" + node_name +
           "' twice: the second channel is ignored");
      continue;
    }
    const std::string where = label + " channel '" + node_name + "'";
    JointChannel out;
    out.joint = found->second;
    for (unsigned k = 0; k < channel->mNumPositionKeys; ++k) {
      const aiVectorKey& key = channel->mPositionKeys[k];
      out.translation_times.push_back(seconds(key.mTime, where));
      if (!finite(key.mValue)) {
        fail(where + " has a non-finite translation key");
      }
      out.translations.emplace_back(key.mValue.x, key.mValue.y, key.mValue.z);
    }
    for (unsigned k = 0; k < channel->mNumRotationKeys; ++k) {
      const aiQuatKey& key = channel->mRotationKeys[k];
      out.rotation_times.push_back(seconds(key.mTime, where));
      Eigen::Quaternionf q(key.mValue.w, key.mValue.x, key.mValue.y,
                           key.mValue.z);
      if (!q.coeffs().allFinite() || !(q.norm() > 0.f)) {
        fail(where + " has a non-finite or zero rotation key");
      }
      out.rotations.push_back(q.normalized());
    }
    for (unsigned k = 0; k < channel->mNumScalingKeys; ++k) {
      const aiVectorKey& key = channel->mScalingKeys[k];
      out.scale_times.push_back(seconds(key.mTime, where));
      if (!finite(key.mValue)) fail(where + " has a non-finite scale key");
      out.scales.emplace_back(key.mValue.x, key.mValue.y, key.mValue.z);
    }
    clip.channels.push_back(std::move(out));
  }
  if (!ignored.empty()) {
    std::string names;
    for (size_t i = 0; i < ignored.size() && i < 5; ++i) {
      names += (i ? ", '" : "'") + ignored[i] + "'";
    }
    if (ignored.size() > 5) names += ", ...";
    warn(label + ": " + std::to_string(ignored.size()) +
         " channels of nodes outside the skeleton ignored (" + names + ")");
  }
  if (first <= last) {
    clip.start = first;
    clip.duration = last - first;
  } else {
    clip.duration = std::max(0.0, anim->mDuration / ticks_per_second);
  }
  rig_.clips.push_back(std::move(clip));
}

// Forwards Assimp's progress (parsing, then post-processing) to
// ImportOptions::progress under the current stage's name.
class ProgressForwarder : public Assimp::ProgressHandler {
 public:
  explicit ProgressForwarder(const ImportOptions& options)
      : options_(options) {}
  bool Update(float percentage) override {
    if (options_.progress && percentage >= 0.f) {
      options_.progress(stage, std::min(percentage, 1.f));
    }
    return true;  // never cancel
  }
  const char* stage = "reading";

 private:
  const ImportOptions& options_;
};

void Loader::report(const char* stage, float fraction) const {
  if (options_.progress) options_.progress(stage, fraction);
}

Rig Loader::load() {
  checkReadable();
  Assimp::Importer importer;
  // The importer owns and deletes its progress handler.
  auto* progress = new ProgressForwarder(options_);
  importer.SetProgressHandler(progress);
  report("reading", 0.f);
  importer.SetPropertyBool(AI_CONFIG_IMPORT_FBX_PRESERVE_PIVOTS, false);
  // A file without meshes must stay without: no made-up skeleton mesh.
  importer.SetPropertyBool(AI_CONFIG_IMPORT_NO_SKELETON_MESHES, true);
  // Read raw first: Assimp's validation rejects a scene without meshes in
  // its own words, and post-processing hides NaN vertices (see
  // checkFiniteMeshes).
  scene_ = importer.ReadFile(path_, 0);
  if (scene_ == nullptr) fail(importer.GetErrorString());
  if (scene_->mNumMeshes == 0) fail("no mesh in the file");
  progress->stage = "processing";
  report("processing", 0.f);
  scene_ = importer.ApplyPostProcessing(aiProcess_ValidateDataStructure);
  if (scene_ == nullptr) fail(importer.GetErrorString());
  checkFiniteMeshes();
  scene_ = importer.ApplyPostProcessing(
      aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
      aiProcess_SortByPType | aiProcess_ValidateDataStructure);
  if (scene_ == nullptr) fail(importer.GetErrorString());
  if (scene_->mRootNode == nullptr) fail("the scene has no node");
  rig_.source = path_;
  report("building", 0.f);

  collectNodes(scene_->mRootNode, -1);
  findMeshNodes();
  buildSkeleton();
  for (unsigned m = 0; m < scene_->mNumMeshes; ++m) {
    addMesh(m);
    report("building", 0.5f * (m + 1) / scene_->mNumMeshes);
  }
  if (rig_.mesh.vertexCount() == 0) {
    fail("no mesh with triangles is attached to the skeleton");
  }
  finishNormals();
  for (const Joint& joint : rig_.skeleton.joints) checkRigid(joint);

  rig_.weights = SkinWeights::fromLists(influences_);
  rig_.weights.normalize(options_.weight_sum_tolerance);
  rig_.weights.sortByWeight();

  for (unsigned a = 0; a < scene_->mNumAnimations; ++a) {
    addClip(a);
    report("building", 0.5f + 0.5f * (a + 1) / scene_->mNumAnimations);
  }
  report("building", 1.f);

  if (Validation v = rig_.validate(); !v) fail(v.reason());
  return std::move(rig_);
}

}  // namespace

Rig importRig(const std::string& path, const ImportOptions& options) {
  if (!options.isolate && options.time_limit_seconds == 0 &&
      options.memory_limit_bytes == 0) {
    return Loader(path, options).load();
  }
  detail::ChildLimits limits;
  limits.time_limit_seconds = options.time_limit_seconds;
  limits.memory_limit_bytes = options.memory_limit_bytes;
  const std::string bytes = detail::runInChildProcess(
      path, limits,
      [&](const detail::ProgressSink& sink) {
        ImportOptions in_child = options;
        in_child.progress = sink;
        return detail::serializeRig(Loader(path, in_child).load());
      },
      options.progress);
  return detail::deserializeRig(bytes);
}

}  // namespace isk
